"""Re-express a canonical motion relative to the canonical T-pose.

Local rotations are relative to the skeleton's rest pose, and rest poses differ between sources:
the CMU conversion's thighs splay 20° outward, DAZ figures stand in an A-pose, spines curve.
The same rotation then means a different pose on another skeleton — copying CMU rotations onto
a straight-legged robot skeleton crosses its legs. Aligning every motion to one rest pose (the
T-pose of ``canonical.default_canonical_skeleton``: spine and neck up, arms along ±X, legs down,
toes forward) makes rotations transferable between skeletons, as the seed papers assume.

For each joint with exactly one child in the canonical tree, the shortest rotation A taking the
T-pose direction of its bone onto the skeleton's rest direction is folded into the joint's
global rotation (G' = G ⊗ A) and the bone's offset becomes length × T-pose direction. Every joint
position is unchanged, because G'·t' = G·A·|s|·t̂ = G·s. Branching joints (Hips, Spine2) keep
their frames and their children's offsets (pelvis and shoulder-girdle geometry), leaf joints
(Head, hands, toes) keep their rotations, and zero-length bones stay as they are.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.skeleton import Skeleton

_UP = (0.0, 1.0, 0.0)
_DOWN = (0.0, -1.0, 0.0)
_LEFT = (1.0, 0.0, 0.0)
_RIGHT = (-1.0, 0.0, 0.0)

# T-pose direction of the bone ending at each joint (canonical frame: Y up, facing +Z, left +X).
TPOSE_BONE_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "Spine1": _UP,
    "Spine2": _UP,
    "Head": _UP,
    "LeftArm": _LEFT,
    "LeftForeArm": _LEFT,
    "LeftHand": _LEFT,
    "RightArm": _RIGHT,
    "RightForeArm": _RIGHT,
    "RightHand": _RIGHT,
    "LeftLeg": _DOWN,
    "LeftFoot": _DOWN,
    "RightLeg": _DOWN,
    "RightFoot": _DOWN,
}

# Toes point forward; their elevation (ankle above the ball of the foot) is anatomy, not pose,
# so only the toe-out yaw is removed.
_TOES = ("LeftToeBase", "RightToeBase")

_MIN_BONE = 1e-9


def tpose_direction(joint: str, rest_offset: FloatArray) -> FloatArray | None:
    """T-pose direction of the bone ending at ``joint``; None where the bone is not aligned."""
    if joint in TPOSE_BONE_DIRECTIONS:
        return np.array(TPOSE_BONE_DIRECTIONS[joint])
    if joint in _TOES:
        length = float(np.linalg.norm(rest_offset))
        if length < _MIN_BONE:  # a toe synthesised at the foot has no direction to keep
            return None
        horizontal = float(np.hypot(rest_offset[0], rest_offset[2]))
        return np.array([0.0, rest_offset[1], horizontal]) / length
    return None


def align_to_tpose(skeleton: Skeleton, global_quats: npt.ArrayLike) -> tuple[Skeleton, FloatArray]:
    """The same motion on a T-pose rest skeleton: (new skeleton, new global rotations (…, J, 4)).

    Joint positions from forward kinematics are identical before and after.
    """
    glob = quat.as_float_array(global_quats).copy()
    offsets = skeleton.offsets.copy()
    for j in range(skeleton.num_joints):
        children = skeleton.children(j)
        if len(children) != 1:
            continue
        c = children[0]
        rest = skeleton.offsets[c]
        length = float(np.linalg.norm(rest))
        target = tpose_direction(skeleton.names[c], rest)
        if target is None or length < _MIN_BONE:
            continue
        align = quat.from_two_vectors(target, rest)  # T-pose direction → rest direction
        glob[..., j, :] = quat.mul(glob[..., j, :], align)
        offsets[c] = length * target
    return skeleton.with_offsets(offsets), glob
