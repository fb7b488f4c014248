"""Checks of a robot config's bones against its own geometry, at the zero pose.

The loader checks each key on its own; these mistakes only show when the bones are placed:

- **a bone that runs backwards** (its ``start`` and ``end`` swapped): a limb's bones join end
  to start (the forearm starts where the upper arm ends), so a bone whose start lies where its
  parent bone starts, or whose end lies where its parent ends, is reversed (or, where the
  parent runs outward from the root link as limbs do, names its parent's start as its own).
  Left in, every solve meets a bone 180° from its target, where the twist's derivative is NaN,
  and the robot stands still (each frame holds the previous command);
- **sides**: a Left bone must lie on the robot's left, a Right bone on its right, left being
  ``up_axis × forward_axis``. All of them on the wrong side is a ``forward_axis`` (or
  ``up_axis``) pointing the wrong way; one is a bone mapped onto the other side's links.

The zero pose is the URDF's reference pose; the shipped robots stand with their limbs apart in
it (OP3's arms out to the sides), as URDF models do.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.errors import ConfigError
from robot_retarget.robot.config import BoneConfig, RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics

JOIN_SHARE = 0.25
"""A bone must start within this share of its parent bone's length of where the parent ends
(the shipped robots' bones share their frames: 0 m)."""


def check_bone_geometry(config: RobotConfig) -> None:
    """Raise ConfigError naming the first bone that runs backwards or lies on the wrong side."""
    kin = RobotKinematics(config)
    names = sorted({f for b in config.bones for f in (b.start_frame, b.end_frame)})
    at = dict(zip(names, kin.frame_positions(np.zeros(config.num_joints), names), strict=True))
    _check_sides(config, at)
    _check_joins(config, at)


def _label(bone: BoneConfig) -> str:
    return f"{bone.canonical} ({bone.start_frame} → {bone.end_frame})"


def _check_joins(config: RobotConfig, at: dict[str, np.ndarray]) -> None:
    index = {b.canonical_end: i for i, b in enumerate(config.bones)}
    for i, bone in enumerate(config.bones):
        if bone.canonical not in index:
            continue  # the first bone of its chain (or its parent is not mapped)
        p = index[bone.canonical]
        parent = config.bones[p]
        p_start, p_end = at[parent.start_frame], at[parent.end_frame]
        tol = JOIN_SHARE * float(np.linalg.norm(p_end - p_start))
        start, end = at[bone.start_frame], at[bone.end_frame]
        gap = float(np.linalg.norm(start - p_end))
        if gap <= tol:
            continue
        if float(np.linalg.norm(start - p_start)) <= tol:
            # Either the parent runs backwards or this bone's start names the parent's start.
            # Limbs run outward: a parent whose start lies nearer the root link than its end
            # (positions are in the root link's frame) runs the right way round.
            if float(np.linalg.norm(p_start)) < float(np.linalg.norm(p_end)):
                raise ConfigError(
                    f"bone {_label(bone)} starts where {_label(parent)} starts, not where it "
                    f"ends: a limb's bones join end to start (start: {parent.end_frame}?)",
                    path=config.source_path,
                    key=f"bones[{i}].start",
                )
            raise _backwards(config, p, f"{bone.canonical} starts at its start, not at its end")
        if float(np.linalg.norm(end - p_end)) <= tol:
            raise _backwards(config, i, f"its end, not its start, is where {parent.canonical} ends")
        raise ConfigError(
            f"bone {_label(bone)} starts {gap:.3f} m from where {_label(parent)} "
            "ends at the zero pose: a limb's bones join end to start",
            path=config.source_path,
            key=f"bones[{i}].start",
        )


def _backwards(config: RobotConfig, i: int, why: str) -> ConfigError:
    return ConfigError(
        f"bone {_label(config.bones[i])} runs backwards: {why} (swap its start and end)",
        path=config.source_path,
        key=f"bones[{i}]",
    )


def _check_sides(config: RobotConfig, at: dict[str, np.ndarray]) -> None:
    left_axis = np.cross(np.asarray(config.up_axis), np.asarray(config.forward_axis))
    wrong: list[tuple[int, BoneConfig, float]] = []
    sided = 0
    for i, bone in enumerate(config.bones):
        if not bone.canonical.startswith(("Left", "Right")):
            continue
        side = 1.0 if bone.canonical.startswith("Left") else -1.0
        sided += 1
        lateral = float(0.5 * (at[bone.start_frame] + at[bone.end_frame]) @ left_axis)
        if side * lateral <= 0.0:
            wrong.append((i, bone, lateral))
    if not wrong:
        return
    if len(wrong) == sided:
        raise ConfigError(
            "every Left bone lies on the robot's right and every Right bone on its left "
            "(left = up_axis × forward_axis, at the zero pose): forward_axis or up_axis points "
            "the wrong way",
            path=config.source_path,
            key="forward_axis",
        )
    i, bone, lateral = wrong[0]
    where = "left" if lateral > 0 else "right" if lateral < 0 else "midline"
    own = "left" if bone.canonical.startswith("Left") else "right"
    raise ConfigError(
        f"bone {_label(bone)} lies on the robot's {where} ({lateral:+.3f} m along up_axis × "
        f"forward_axis at the zero pose): a {own} bone on the other side's links, or a wrong "
        "forward_axis or up_axis?",
        path=config.source_path,
        key=f"bones[{i}]",
    )
