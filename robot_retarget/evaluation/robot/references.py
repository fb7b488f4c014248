"""The two references of eval-robot, built from the human motion alone (plus candidates).

- :func:`baseline_targets` / :class:`BaselineRunner`: the position-IK baseline's targets — each
  limb's keypoints (elbow, hand; knee, ankle) relative to the limb's root joint (shoulder, hip),
  turned into the body frame, scaled by robot limb length / human limb length and attached at
  the robot's limb root (its first bone's start frame at the zero pose);
- :func:`limit_segments`: the segments of :mod:`.segments` as frame lists for
  :class:`robot_retarget.optimize.kinematic_limit.KinematicLimit`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.robot.segments import (
    RobotSegmentFrames,
    body_axes,
    robot_segment_frames,
    to_body,
)
from robot_retarget.optimize.bone_model import body_to_root
from robot_retarget.optimize.kinematic_limit import SegmentFrames
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.trunk import trunk_frames_of_positions

CANONICAL_UP = np.array([0.0, 1.0, 0.0])
# (limb root, middle, end) canonical joints, and the robot bones' indices in SEGMENTS order:
# (upper-arm / thigh index, forearm / shin index).
LIMBS: tuple[tuple[str, str, str, int, int], ...] = (
    ("LeftArm", "LeftForeArm", "LeftHand", 0, 2),
    ("RightArm", "RightForeArm", "RightHand", 1, 3),
    ("LeftUpLeg", "LeftLeg", "LeftFoot", 4, 6),
    ("RightUpLeg", "RightLeg", "RightFoot", 5, 7),
)


def baseline_points(frames: RobotSegmentFrames) -> tuple[str, ...]:
    """Robot frames the baseline drives: elbows, hands, knees, ankles (the bones' ends)."""
    return tuple(f for _, _, _, a, b in LIMBS for f in (frames.ends[a], frames.ends[b]))


def baseline_targets(config: RobotConfig, positions: npt.ArrayLike) -> FloatArray:
    """(T, 8, 3) targets (m, root frame) for :func:`baseline_points` from canonical global
    positions (T, 22, 3): human keypoints in the body frame, scaled per limb to the robot."""
    pos = np.asarray(positions, dtype=np.float64)
    frames = robot_segment_frames(config)
    kin = RobotKinematics(config)
    zero = np.zeros(config.num_joints)
    p0 = kin.frame_positions(zero, [*frames.starts, *frames.ends])
    robot_len = np.linalg.norm(p0[8:] - p0[:8], axis=-1)
    axes = trunk_frames_of_positions(pos).transpose(0, 2, 1)  # rows: the trunk frame
    to_root = body_to_root(config)  # columns: forward, left, up in the root frame
    out = []
    for root, mid, end, a, b in LIMBS:
        r, m, e = pos[:, Joint[root]], pos[:, Joint[mid]], pos[:, Joint[end]]
        human_len = np.linalg.norm(m - r, axis=-1) + np.linalg.norm(e - m, axis=-1)
        scale = (robot_len[a] + robot_len[b]) / np.maximum(human_len, 1e-9)
        rel = to_body(axes, np.stack([m - r, e - r], axis=1)) * scale[:, None, None]
        out.append(p0[a] + np.einsum("ij,tkj->tki", to_root, rel))
    return np.concatenate(out, axis=1)


def limit_segments(frames: RobotSegmentFrames) -> tuple[SegmentFrames, ...]:
    """The scored segments as (start frames, end frames), SEGMENTS order."""
    limbs = tuple(((s,), (e,)) for s, e in zip(frames.starts, frames.ends, strict=True))
    return (*limbs, (frames.hips, frames.shoulders))


def robot_body_axes(config: RobotConfig, frames: RobotSegmentFrames) -> FloatArray:
    """(3, 3) rows forward, left, up of the robot's body frame in its root frame (the hips are
    trunk points, rigid in the root, so this is constant)."""
    p = RobotKinematics(config).frame_positions(np.zeros(config.num_joints), list(frames.hips))
    return body_axes(p[0], p[1], np.asarray(config.up_axis, dtype=np.float64))
