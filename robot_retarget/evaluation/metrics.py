"""Retargeting quality metrics on joint positions and rotations (numpy only).

Positions are global joint positions (T, 22, 3) in metres on the canonical skeleton (Y up),
as ``HumanMotion.positions()`` returns them. Every metric is normalised so that skeletons of
different sizes (a person, a 0.5 m robot) are comparable:

- :func:`position_error`: SAN's reconstruction / cycle error, the mean squared joint-position
  error of motions on the *same* skeleton, positions divided by the skeleton's height, × 10³;
- :func:`end_effector_error`: hands and feet relative to the root, divided by arm / leg length,
  target versus source (mean Euclidean distance, in limb lengths);
- :func:`contact_distance_error`: distances hand–hand, hand–head, hand–hip, foot–foot divided by
  arm / leg length, |target − source| (limb lengths);
- :func:`bone_direction_error_deg`: angle between each bone's global direction on source and
  target (degrees), bones of zero length on either side skipped;
- :func:`twist_share`: share of (frame, joint) local rotations twisting more than α about
  their bone (NKN's and PMnet's α = 100°).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.skeleton_measures import arm_length, leg_length
from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint
from robot_retarget.skeleton.skeleton import Skeleton

TWIST_ALPHA_RAD = math.radians(100.0)
_MIN_BONE_M = 1e-6

HANDS: tuple[int, ...] = (Joint.LeftHand, Joint.RightHand)
FEET: tuple[int, ...] = (Joint.LeftFoot, Joint.RightFoot)

# (joint a, joint b, normalising limb): the contacts that matter when retargeting.
CONTACT_PAIRS: tuple[tuple[int, int, str], ...] = (
    (Joint.LeftHand, Joint.RightHand, "arm"),
    (Joint.LeftHand, Joint.Head, "arm"),
    (Joint.RightHand, Joint.Head, "arm"),
    (Joint.LeftHand, Joint.Hips, "arm"),
    (Joint.RightHand, Joint.Hips, "arm"),
    (Joint.LeftFoot, Joint.RightFoot, "leg"),
)


def _positions(name: str, pos: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(pos, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must be (T, J, 3) joint positions, got {arr.shape}")
    return arr


def _same_shape(a: FloatArray, b: FloatArray) -> None:
    if a.shape != b.shape:
        raise ValueError(f"motions differ in shape: {a.shape} vs {b.shape}")


def position_error(pred: npt.ArrayLike, ref: npt.ArrayLike, height_m: float) -> float:
    """Mean over frames and joints of ‖(p̂ − p) / height‖², × 10³ (SAN's error)."""
    p = _positions("pred", pred)
    r = _positions("ref", ref)
    _same_shape(p, r)
    if not height_m > 0.0:
        raise ValueError(f"height must be positive, got {height_m}")
    return float(np.mean(np.sum(((p - r) / height_m) ** 2, axis=-1)) * 1e3)


def _effectors(pos: FloatArray, skeleton: Skeleton) -> FloatArray:
    """Hands and feet relative to the root, in limb lengths: (T, 4, 3)."""
    rel = pos[:, HANDS + FEET] - pos[:, Joint.Hips, None]
    scale = np.array([arm_length(skeleton)] * 2 + [leg_length(skeleton)] * 2)
    return np.asarray(rel / scale[None, :, None], dtype=np.float64)


def end_effector_error(
    src_pos: npt.ArrayLike, src_skeleton: Skeleton, tgt_pos: npt.ArrayLike, tgt_skeleton: Skeleton
) -> float:
    """Mean distance (limb lengths) between source and target hands and feet, each relative to
    the root and divided by its arm or leg length."""
    s = _positions("src_pos", src_pos)
    t = _positions("tgt_pos", tgt_pos)
    _same_shape(s, t)
    diff = _effectors(t, tgt_skeleton) - _effectors(s, src_skeleton)
    return float(np.mean(np.linalg.norm(diff, axis=-1)))


def contact_distances(pos: npt.ArrayLike, skeleton: Skeleton) -> FloatArray:
    """Distances (T, len(CONTACT_PAIRS)) of the contact pairs, in arm or leg lengths."""
    p = _positions("pos", pos)
    limbs = {"arm": arm_length(skeleton), "leg": leg_length(skeleton)}
    cols = [
        np.linalg.norm(p[:, a] - p[:, b], axis=-1) / limbs[limb] for a, b, limb in CONTACT_PAIRS
    ]
    return np.stack(cols, axis=-1)


def contact_distance_error(
    src_pos: npt.ArrayLike, src_skeleton: Skeleton, tgt_pos: npt.ArrayLike, tgt_skeleton: Skeleton
) -> float:
    """Mean |d_target − d_source| over frames and contact pairs (limb lengths)."""
    s = _positions("src_pos", src_pos)
    t = _positions("tgt_pos", tgt_pos)
    _same_shape(s, t)
    diff = contact_distances(t, tgt_skeleton) - contact_distances(s, src_skeleton)
    return float(np.mean(np.abs(diff)))


def bone_direction_error_deg(
    src_pos: npt.ArrayLike,
    src_skeleton: Skeleton,
    tgt_pos: npt.ArrayLike,
    tgt_skeleton: Skeleton,
) -> float:
    """Mean angle (degrees) between source and target global bone directions.

    Bones (joint − parent) that have zero length on either skeleton (synthesised joints,
    e.g. DAZ's Spine1) are skipped.
    """
    s = _positions("src_pos", src_pos)
    t = _positions("tgt_pos", tgt_pos)
    _same_shape(s, t)
    parents = np.array(CANONICAL_PARENTS)
    children = np.array(
        [
            j
            for j in range(1, len(CANONICAL_PARENTS))
            if src_skeleton.bone_lengths()[j] > _MIN_BONE_M
            and tgt_skeleton.bone_lengths()[j] > _MIN_BONE_M
        ]
    )
    bs = s[:, children] - s[:, parents[children]]
    bt = t[:, children] - t[:, parents[children]]
    cos = np.sum(bs * bt, axis=-1) / (np.linalg.norm(bs, axis=-1) * np.linalg.norm(bt, axis=-1))
    return float(np.degrees(np.mean(np.arccos(np.clip(cos, -1.0, 1.0)))))


def twist_axes(skeleton: Skeleton) -> FloatArray:
    """Bone axis (J, 3) each joint's twist is measured about, in the joint's own frame.

    The direction to the joint's first child of non-zero length, else its own offset, else
    up (+Y) — the convention of the training losses (robot_retarget.nn.losses.twist_axes).
    """
    offsets = skeleton.offsets
    lengths = skeleton.bone_lengths()
    axes = np.zeros((skeleton.num_joints, 3))
    for i in range(skeleton.num_joints):
        candidates = [*skeleton.children(i), i]
        chosen = next((c for c in candidates if lengths[c] > _MIN_BONE_M), None)
        axes[i] = [0.0, 1.0, 0.0] if chosen is None else offsets[chosen] / lengths[chosen]
    return axes


def twist_share(
    local_quats: npt.ArrayLike, skeleton: Skeleton, alpha_rad: float = TWIST_ALPHA_RAD
) -> float:
    """Share (0–1) of (frame, non-root joint) rotations whose twist exceeds ``alpha_rad``."""
    q = quat.as_float_array(local_quats)
    if q.ndim != 3 or q.shape[1:] != (skeleton.num_joints, 4):
        raise ValueError(f"local_quats must be (T, {skeleton.num_joints}, 4), got {q.shape}")
    angles = quat.twist_angle(q[:, 1:], twist_axes(skeleton)[1:])
    return float(np.mean(np.abs(angles) > alpha_rad))
