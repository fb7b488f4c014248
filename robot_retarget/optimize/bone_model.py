"""How each canonical bone lives on the robot: frames, carrier link, rest axis, parent bone.

Rotations of bones are compared "relative to the canonical T-pose", in the robot root frame:

- ``M0`` maps canonical rest coordinates (Y up, facing +Z, left = +X) into the robot root frame
  through the robot's ``up_axis`` / ``forward_axis``.
- A human bone's rotation is ``G_h = M_t · G_canon · M0ᵀ`` (``M_t`` adds the heading-free body
  frame of the current frame, see :mod:`.targets`).
- A robot bone's rotation is ``G_r(q) = R_carrier(q) · C`` with the constant
  ``C = R_carrier(0)ᵀ · S``, where ``S`` is the shortest arc taking the canonical rest direction
  (mapped by ``M0``) onto the robot's bone at q = 0. For robots whose zero pose is a T-pose
  (OP3) ``S`` is the identity; for arms-down zero poses it swings the bone down.

Both give the same bone direction for the same pose; their difference in roll about the bone is
what the orientation cost and the twist bound see. The twist of a bone is that of its local
rotation ``G_parentᵀ · G`` about its rest axis (swing–twist, as in NKN / PMnet / TDCN).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ConfigError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.robot.config import RobotConfig
from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    END_EFFECTORS,
    default_canonical_skeleton,
)

_FEET = (("LeftToeBase", "RightToeBase"), ("LeftFoot", "RightFoot"))


@dataclass(frozen=True)
class BoneGeometry:
    """One mapped bone; vectors are unit, in the robot root frame."""

    canonical: str
    canonical_end: str
    start_frame: str
    end_frame: str
    carrier_link: str  # robot link whose rotation the bone follows
    carrier_joint: int  # canonical joint whose global rotation moves the bone
    parent: int  # index of the parent bone (for the twist), −1: the root
    rest_axis: FloatArray  # canonical rest direction, M0-mapped
    rest_normal: FloatArray  # a unit vector ⟂ rest_axis, M0-mapped


def body_to_root(config: RobotConfig) -> FloatArray:
    """Columns: the robot's forward, left and up axes (a heading-free body frame, x fwd, z up)."""
    up = np.asarray(config.up_axis, dtype=np.float64)
    fwd = np.asarray(config.forward_axis, dtype=np.float64)
    up = up / np.linalg.norm(up)
    fwd = fwd - up * float(fwd @ up)
    norm = float(np.linalg.norm(fwd))
    if norm < 1e-6:
        raise ConfigError(
            f"robot {config.name}: forward_axis {config.forward_axis} is parallel to up_axis",
            path=config.source_path,
            key="forward_axis",
            allowed="a direction not parallel to up_axis",
        )
    fwd = fwd / norm
    return np.column_stack([fwd, np.cross(up, fwd), up])


# Canonical rest body frame (x fwd = +Z, y left = +X, z up = +Y) as columns.
CANONICAL_BODY = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def canonical_to_root(config: RobotConfig) -> FloatArray:
    """M0: canonical rest coordinates → robot root frame."""
    return np.asarray(body_to_root(config) @ CANONICAL_BODY.T, dtype=np.float64)


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v), dtype=np.float64)


def _rest_normal(axis: FloatArray) -> FloatArray:
    """Canonical forward (+Z) made perpendicular to the bone; up (+Y) for bones along Z."""
    for helper in (np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])):
        n = helper - axis * float(helper @ axis)
        if np.linalg.norm(n) > 0.3:
            return _unit(n)
    raise ValueError("unreachable: +Z and +Y cannot both be parallel to one axis")


def build_bones(config: RobotConfig, carrier_of: dict[str, str]) -> tuple[BoneGeometry, ...]:
    """Geometry of every mapped bone. ``carrier_of`` maps an end frame to its carrier link."""
    m0 = canonical_to_root(config)
    rest = default_canonical_skeleton().rest_positions()
    index = {n: i for i, n in enumerate(CANONICAL_JOINTS)}
    carriers: list[int] = []
    bones: list[BoneGeometry] = []
    for b in config.bones:
        for name in (b.canonical, b.canonical_end):
            if name not in index:
                raise ConfigError(
                    f"robot {config.name}: bone names unknown canonical joint {name!r}",
                    path=config.source_path,
                    key="bones",
                    allowed=", ".join(CANONICAL_JOINTS),
                )
        end = index[b.canonical_end]
        carrier = CANONICAL_PARENTS[end]
        if carrier < 0:
            raise ConfigError(
                f"robot {config.name}: bone {b.canonical}→{b.canonical_end} ends at the root",
                path=config.source_path,
                key="bones",
                allowed="bones that end at a non-root canonical joint",
            )
        carriers.append(carrier)
    for k, b in enumerate(config.bones):
        axis_c = rest[index[b.canonical_end]] - rest[index[b.canonical]]
        if np.linalg.norm(axis_c) < 1e-9:
            raise ConfigError(
                f"robot {config.name}: bone {b.canonical}→{b.canonical_end} has zero length "
                "in the canonical skeleton",
                path=config.source_path,
                key="bones",
                allowed="two distinct canonical joints",
            )
        axis_c = _unit(axis_c)
        # Parent: the nearest canonical ancestor of this bone's carrier that carries a bone.
        parent = -1
        a = CANONICAL_PARENTS[carriers[k]]
        while a >= 0 and parent < 0:
            parent = next((i for i, c in enumerate(carriers) if c == a and i != k), -1)
            a = CANONICAL_PARENTS[a]
        bones.append(
            BoneGeometry(
                canonical=b.canonical,
                canonical_end=b.canonical_end,
                start_frame=b.start_frame,
                end_frame=b.end_frame,
                carrier_link=carrier_of[b.end_frame],
                carrier_joint=carriers[k],
                parent=parent,
                rest_axis=_unit(m0 @ axis_c),
                rest_normal=_unit(m0 @ _rest_normal(axis_c)),
            )
        )
    return tuple(bones)


def alignment(
    bone: BoneGeometry, dir_at_zero: FloatArray, r_carrier_at_zero: FloatArray
) -> FloatArray:
    """C with G_r(q) = R_carrier(q) · C (see the module docstring)."""
    s = quat.to_matrix(quat.from_two_vectors(bone.rest_axis, dir_at_zero))
    return np.asarray(r_carrier_at_zero.T @ s, dtype=np.float64)


def end_effector_frames(config: RobotConfig) -> tuple[tuple[str, str], ...]:
    """(canonical end effector, robot frame) for every END_EFFECTOR some bone ends at."""
    out = []
    for name in END_EFFECTORS:
        frame = next((b.end_frame for b in config.bones if b.canonical_end == name), None)
        if frame is not None:
            out.append((name, frame))
    return tuple(out)


def foot_frames(config: RobotConfig) -> tuple[str, ...]:
    """Robot frames kept above the ground: toe ends if mapped, else foot (ankle) ends."""
    for names in _FEET:
        frames = tuple(b.end_frame for b in config.bones if b.canonical_end in names)
        if frames:
            return frames
    return ()
