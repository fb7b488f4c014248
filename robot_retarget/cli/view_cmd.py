"""``view TRAJ [--clip SOURCE.bvh]``: a recorded robot trajectory in the browser.

Serves a page (viser, the ``[view]`` extra) with the robot at its floating-base pose on a
ground grid, the performer beside it when ``--clip`` names the clip the trajectory was
converted from, a timeline and per-joint plots with the joint and speed limits. Runs until
Ctrl-C.
"""

from __future__ import annotations

import argparse
import sys
import threading
import webbrowser
from pathlib import Path
from typing import TYPE_CHECKING

from robot_retarget.cli.tcp_port_arg import tcp_port_argument

if TYPE_CHECKING:
    from robot_retarget.motion.trajectory import RobotTrajectory

NAME = "view"
HELP = "Show a trajectory and its clip in a browser."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("trajectory", type=Path, metavar="TRAJ", help="TRAJ.npz|.csv|.json")
    parser.add_argument(
        "--clip", type=Path, help="the BVH clip it was converted from: drawn beside the robot"
    )
    parser.add_argument(
        "--robot", help="robot config name or YAML (default: the bundled robot with its joints)"
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to serve on")
    parser.add_argument(
        "--port",
        type=tcp_port_argument,
        default=8080,
        help="port (the next free one if it is busy)",
    )
    parser.add_argument(
        "--no-browser", action="store_true", help="serve only; do not open a browser"
    )


def run(args: argparse.Namespace) -> int:
    from robot_retarget.motion.trajectory import RobotTrajectory
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.viewer.dependency import require_viser
    from robot_retarget.viewer.robot_match import robot_for_trajectory
    from robot_retarget.viewer.scene import RobotFigure, performer_figure
    from robot_retarget.viewer.trajectory_page import TrajectoryPage

    require_viser()  # before any work: the install hint comes first
    trajectory = RobotTrajectory.read(args.trajectory)
    config = load_robot_config(args.robot) if args.robot else robot_for_trajectory(trajectory)
    performer = None
    if args.clip is not None:
        from robot_retarget.motion.human_motion import load_motion

        motion = load_motion(args.clip)
        warning = clip_mismatch(motion.duration_s, motion.fps, trajectory)
        if warning is not None:
            print(f"warning: {warning}", file=sys.stderr)
        side = 1.2 * RobotFigure(config).height_m()
        performer = performer_figure(motion, config, offset=(0.0, side, 0.0))
    page = TrajectoryPage(config, trajectory, performer, host=args.host, port=args.port)
    print(
        f"robot {config.name}, {trajectory.num_frames} frames at {trajectory.fps:g} fps: "
        f"{page.url} (Ctrl-C to stop)",
        file=sys.stderr,
    )
    if not args.no_browser:
        webbrowser.open(page.url)
    try:
        threading.Event().wait()
    finally:
        page.close()
    return 0


def clip_mismatch(clip_s: float, clip_fps: float, trajectory: RobotTrajectory) -> str | None:
    """Why ``--clip`` looks like another clip than the trajectory's (its length differs from
    the trajectory's own frames, the lead-in left out, by more than a frame of either), or
    None. A conversion with --max-frames is shorter than its clip: said, not refused."""
    own = trajectory.num_frames - int((trajectory.times_s() < -1e-9).sum())
    traj_s = own / trajectory.fps
    if abs(traj_s - clip_s) <= 1.0 / clip_fps + 1.0 / trajectory.fps:
        return None
    return (
        f"--clip is {clip_s:.2f} s long and the trajectory {traj_s:.2f} s: is it the clip the "
        "trajectory was converted from (or a part of it, with --max-frames)? The two are drawn "
        "from the same start."
    )
