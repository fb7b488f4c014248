"""``inspect FILE|DIR...``: describe motion files (skeleton family, mapping, frames, units),
robot trajectories (.npz / .csv / .json: robot, lead-in, base, limits; see
:mod:`robot_retarget.cli.trajectory_facts`) and 2D keypoint input (frames, image, what the
estimator missed; :mod:`robot_retarget.cli.keypoint_facts`).

A folder (other than an OpenPose JSON folder) stands for every .bvh file under it (subfolders
included, sorted by path), as ``convert`` reads folders. Each file is reported on its own; a
file that cannot be read, a missing path or a folder without .bvh files gets a one-line error
on stderr and the others are still reported. The exit code is 1 if any failed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from robot_retarget.cli.keypoint_facts import (
    describe_keypoints,
    format_keypoints_text,
    is_keypoint_file,
)
from robot_retarget.cli.robot_bvh_facts import (
    describe_robot_bvh,
    format_robot_bvh_text,
    robot_of_bvh,
)
from robot_retarget.cli.robot_config_facts import (
    describe_robot_config,
    format_robot_config_text,
    is_robot_config,
)
from robot_retarget.cli.trajectory_facts import (
    describe_trajectory,
    format_trajectory_text,
    is_trajectory_file,
)
from robot_retarget.errors import JointMappingError, MotionFormatError, RetargetError
from robot_retarget.motion.bvh import BvhClip, read_bvh
from robot_retarget.motion.canonicalize import canonicalize
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.native_pose import native_pose
from robot_retarget.motion.units import UNIT_SCALES_M
from robot_retarget.skeleton.armatures import TopologyError
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

NAME = "inspect"
HELP = "Describe motion files, keypoint input, robot trajectories and robot configs."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "files",
        nargs="+",
        metavar="FILE|DIR",
        help="BVH files, folders of BVH files, 2D keypoint input (an OpenPose JSON folder, "
        "MediaPipe .json, COCO-17 .jsonl), robot trajectories (.npz, .csv, .json with "
        "joint_names: robot, lead-in, base, feet, limits) or robot configs (.yaml: checked as "
        "convert reads them, then summarised)",
    )
    parser.add_argument(
        "--json",
        action="store_true",
        help="print a JSON list, one object per file (a file that cannot be read: {file, error})",
    )
    parser.add_argument(
        "--unit",
        choices=sorted(UNIT_SCALES_M),
        help="length unit of the files (default: detected from the skeleton's height)",
    )
    parser.add_argument(
        "--keep-tpose", action="store_true", help="keep a synthetic first T-pose frame"
    )
    parser.add_argument(
        "--robot",
        help="the robot a trajectory or robot BVH is for (default: the bundled robot with exactly "
        "its joints, or links)",
    )


def describe(
    path: str, *, unit: str | None = None, keep_tpose: bool = False, clip: BvhClip | None = None
) -> dict[str, Any]:
    """Facts about one motion file, as JSON-ready values (``clip``: the file, already read)."""
    clip = read_bvh(path) if clip is None else clip
    motion = canonicalize(clip, unit=unit, drop_tpose=False if keep_tpose else "auto")
    mapping = dict(zip(CANONICAL_JOINTS, motion.source_joints, strict=True))
    return {
        "file": path,
        "family": motion.name_family,
        "joints": clip.num_joints,
        "end_sites": len(clip.end_site_parents),
        "mapping": mapping,
        "synthesized": list(motion.synthesized_joints),
        "frames": motion.num_frames,
        "file_frames": clip.num_frames,
        "fps": motion.fps,
        "duration_s": motion.duration_s,
        "unit": motion.unit,
        "height_m": motion.height_m,
        "up_axis": motion.up_axis,
        "tpose_dropped": motion.dropped_tpose,
        "tpose_frames_dropped": motion.tpose_frames_dropped,
        "armatures": _armatures(clip, motion),
    }


def _armatures(clip: BvhClip, motion: HumanMotion) -> dict[str, Any]:
    """How a skeleton-aware model (SAN) reads the file: its own skeleton as armatures, or
    why it cannot (not homeomorphic to the canonical skeleton)."""
    try:
        topology = native_pose(clip, motion).topology
    except TopologyError as exc:
        return {"skeleton": None, "why_not": str(exc)}
    return {
        "skeleton": topology.name,
        "kept": topology.num_armatures - 1,
        "names": list(topology.armature_names[1:]),
    }


def format_text(info: dict[str, Any]) -> str:
    mapped = [f"{c}←{s}" for c, s in info["mapping"].items() if s is not None]
    synth = ", ".join(info["synthesized"]) or "none"
    tpose = f"yes ({info['tpose_frames_dropped']} frame(s))" if info["tpose_dropped"] else "no"
    return "\n".join(
        [
            f"{info['file']}",
            f"  family:      {info['family']}",
            f"  joints:      {info['joints']} (+{info['end_sites']} end sites)",
            f"  mapped:      {len(mapped)}/{len(info['mapping'])}: {', '.join(mapped)}",
            f"  synthesised: {synth}",
            f"  frames:      {info['frames']} at {info['fps']:.6g} fps "
            f"({info['duration_s']:.3f} s)",
            f"  unit:        {info['unit']} (height {info['height_m']:.3f} m, "
            f"{info['up_axis']} up)",
            f"  T-pose dropped: {tpose}",
            f"  own skeleton (SAN): {_armature_text(info['armatures'])}",
        ]
    )


def _armature_text(armatures: dict[str, Any]) -> str:
    if armatures["skeleton"] is None:
        return f"none: {armatures['why_not']}"
    return f"{armatures['skeleton']}, {armatures['kept']} joints on the chains kept"


def expand_paths(paths: list[str]) -> list[str | MotionFormatError]:
    """Files as given; a folder → every .bvh under it (sorted); a folder without any, or a
    missing path, → the error to report in its place."""
    out: list[str | MotionFormatError] = []
    for path in paths:
        p = Path(path)
        if not p.is_dir() or is_keypoint_file(path):
            out.append(path)
            continue
        clips = sorted(c for c in p.rglob("*") if c.suffix.lower() == ".bvh" and c.is_file())
        if not clips:
            out.append(MotionFormatError("no .bvh files in this folder", path=p))
        out.extend(str(c) for c in clips)
    return out


def _describe_human(path: str, clip: Any, args: argparse.Namespace) -> dict[str, Any]:
    """A performer's BVH; one whose joints map onto no human may be a robot's own BVH for a
    robot not bundled, which only --robot can tell."""
    try:
        return describe(path, unit=args.unit, keep_tpose=args.keep_tpose, clip=clip)
    except JointMappingError as exc:
        if args.robot is not None:
            raise
        exc.args = (
            f"{exc.args[0]} (if this is a robot's own BVH, written by convert --bvh-out for a "
            "robot of your own, pass --robot with its config)",
        )
        raise


def run(args: argparse.Namespace) -> int:
    reports: list[dict[str, Any]] = []
    failed = 0
    for path in expand_paths(args.files):
        try:
            if isinstance(path, MotionFormatError):
                raise path
            if is_robot_config(path):
                info = describe_robot_config(path)
                text = format_robot_config_text(info)
            elif is_keypoint_file(path):
                info = describe_keypoints(path)
                text = format_keypoints_text(info)
            elif is_trajectory_file(path):
                info = describe_trajectory(path, robot=args.robot)
                text = format_trajectory_text(info)
            else:
                clip = read_bvh(path)
                robot = robot_of_bvh(clip, args.robot)
                if robot is not None:  # a robot's own skeleton (convert --bvh-out)
                    info = describe_robot_bvh(path, clip, robot)
                    text = format_robot_bvh_text(info)
                else:
                    info = _describe_human(path, clip, args)
                    text = format_text(info)
        except RetargetError as exc:
            failed += 1
            print(f"error: {exc}", file=sys.stderr)
            if args.json:  # in the list too, so a reader of it sees every file it asked for
                where = path.path if isinstance(path, MotionFormatError) else path
                reports.append({"file": where, "error": str(exc)})
            continue
        if args.json:
            reports.append(info)
        else:
            print(text)
    if args.json:
        print(json.dumps(reports, indent=2))
    return 1 if failed else 0
