"""``inspect`` of a robot trajectory (``convert``'s or ``stream --record``'s NPZ / CSV / JSON):
which robot, how long, a lead-in, the floating base and where its feet are, and whether every
row keeps the robot's joint and velocity limits — what to know before playing a file on a
robot.

The robot is the one named by ``--robot``, else the bundled config with exactly the file's
joints (as ``view`` guesses it). Limits are checked as ``convert`` checks its files: steps from
the robot's init pose when the file has a lead-in (it starts there), else between rows only.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.errors import MotionFormatError
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.config import RobotConfig
from robot_retarget.viewer.robot_match import RobotGuessError, joint_angles_for

TRAJECTORY_SUFFIXES = (".npz", ".csv", ".json")


def describe_trajectory(path: str, *, robot: str | None = None) -> dict[str, Any]:
    """Facts about one trajectory file, as JSON-ready values (``robot`` None and ``robot_why``
    set where no robot could be told: the limits and feet are then left out)."""
    if _is_model_runtime(Path(path)):
        raise MotionFormatError(
            "a model's numpy runtime (written by train or export), not a trajectory; pass it "
            "to convert or stream as --model",
            path=Path(path),
        )
    traj = RobotTrajectory.read(path)
    lead_in = int(np.count_nonzero(traj.times_s() < -1e-9))
    info: dict[str, Any] = {
        "file": path,
        "kind": "robot trajectory",
        "joints": len(traj.joint_names),
        "frames": traj.num_frames,
        "fps": traj.fps,
        "duration_s": traj.num_frames / traj.fps,
        "t0_s": traj.t0,
        "lead_in_frames": lead_in,
        "base": traj.root_pos is not None and traj.root_quat is not None,
        "solve_ms_median": None
        if traj.frame_ms is None or lead_in >= traj.num_frames
        else float(np.median(traj.frame_ms[lead_in:])),
        "robot": None,
    }
    try:
        config = _robot(traj, robot)
    except RobotGuessError as exc:  # a robot named by --robot that does not fit is an error
        info["robot_why"] = str(exc)
        return info
    info["robot"] = config.name
    q = joint_angles_for(config, traj)
    info.update(_limits(config, q, traj.fps, from_init_pose=lead_in > 0))
    if traj.root_pos is not None and traj.root_quat is not None:
        info.update(_base(config, q, traj.root_pos, traj.root_quat, lead_in))
    return info


def _is_model_runtime(path: Path) -> bool:
    from robot_retarget.runtime.npz_file import META_KEY

    if path.suffix.lower() != ".npz":
        return False
    try:
        with zipfile.ZipFile(path) as archive:
            return f"{META_KEY}.npy" in archive.namelist()
    except (OSError, zipfile.BadZipFile):
        return False  # the trajectory reader names what is wrong with it


def _robot(traj: RobotTrajectory, name: str | None) -> RobotConfig:
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.viewer.robot_match import robot_for_trajectory

    if name is None:
        return robot_for_trajectory(traj)
    return load_robot_config(name)  # its joints are checked by joint_angles_for


def _limits(
    config: RobotConfig, q: np.ndarray, fps: float, *, from_init_pose: bool
) -> dict[str, Any]:
    from robot_retarget.pipeline.convert import check_limits

    start = config.init_pose if from_init_pose else None
    check = check_limits(config, q, 1.0 / fps, q_start=start)
    return {
        "limits_ok": check.ok,
        "position_excess_rad": check.position_excess_rad,
        "velocity_excess_rad": check.velocity_excess_rad,
    }


def _base(
    config: RobotConfig, q: np.ndarray, root_pos: np.ndarray, root_quat: np.ndarray, lead_in: int
) -> dict[str, Any]:
    from robot_retarget.pipeline.floating_base import trajectory_feet

    lowest = trajectory_feet(config, q, root_pos, root_quat)[:, :, 2].min(axis=1)
    path = np.linalg.norm(np.diff(root_pos[:, :2], axis=0), axis=1).sum()
    out = {
        "base_height_m": [float(root_pos[:, 2].min()), float(root_pos[:, 2].max())],
        "base_path_m": float(path),
        "lowest_foot_m": [float(lowest.min()), float(lowest.max())],
    }
    if lead_in:
        out["lead_in_lowest_foot_m"] = [
            float(lowest[:lead_in].min()),
            float(lowest[:lead_in].max()),
        ]
    return out


def format_trajectory_text(info: dict[str, Any]) -> str:
    lead = (
        f", {info['lead_in_frames']} of them a lead-in from t0 = {info['t0_s']:.3f} s"
        if info["lead_in_frames"]
        else ""
    )
    lines = [
        f"{info['file']}",
        f"  kind:        robot trajectory, {info['joints']} joints",
        f"  frames:      {info['frames']} at {info['fps']:.6g} fps ({info['duration_s']:.3f} s"
        f"{lead})",
    ]
    if info["solve_ms_median"] is not None:
        lines.append(f"  solve time:  {info['solve_ms_median']:.3f} ms median per frame")
    if info["robot"] is None:
        lines.append(f"  robot:       unknown ({info['robot_why']})")
        return "\n".join(lines)
    limits = (
        "respected"
        if info["limits_ok"]
        else f"EXCEEDED (position by {info['position_excess_rad']:.4f} rad, velocity by "
        f"{info['velocity_excess_rad']:.4f} rad per frame)"
    )
    lines += [f"  robot:       {info['robot']}", f"  limits:      {limits}"]
    if not info["base"]:
        lines.append("  base:        none (joint angles only, as a stream records them)")
        return "\n".join(lines)
    lines += [
        f"  base:        height {info['base_height_m'][0]:.3f}–{info['base_height_m'][1]:.3f} m, "
        f"path {info['base_path_m']:.2f} m (Z-up world)",
        f"  lowest foot: {_cm_range(info['lowest_foot_m'])} above the floor",
    ]
    if "lead_in_lowest_foot_m" in info:
        lines.append(f"  … in the lead-in: {_cm_range(info['lead_in_lowest_foot_m'])}")
    return "\n".join(lines)


def _cm_range(metres: list[float]) -> str:
    low, high = (round(m * 100, 1) + 0.0 for m in metres)  # + 0.0: no "-0.0"
    return f"{low:+.1f} to {high:+.1f} cm"


def is_trajectory_file(path: str) -> bool:
    """A file ``inspect`` reads as a robot trajectory: by its suffix."""
    return Path(path).suffix.lower() in TRAJECTORY_SUFFIXES
