"""Sizes of a canonical skeleton that metrics normalise by: height, arm and leg length."""

from __future__ import annotations

import numpy as np

from robot_retarget.motion.human_motion import skeleton_height
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.skeleton import Skeleton

_SIDES = ("Left", "Right")

# Height is measured as HumanMotion.height_m measures it; re-exported for the metrics.
__all__ = ["arm_length", "leg_length", "skeleton_height"]


def arm_length(skeleton: Skeleton) -> float:
    """Upper arm + forearm (m), mean of both sides: shoulder joint to wrist."""
    lengths = skeleton.bone_lengths()
    return float(
        np.mean([lengths[Joint[s + "ForeArm"]] + lengths[Joint[s + "Hand"]] for s in _SIDES])
    )


def leg_length(skeleton: Skeleton) -> float:
    """Thigh + shin (m), mean of both sides: hip joint to ankle."""
    lengths = skeleton.bone_lengths()
    return float(np.mean([lengths[Joint[s + "Leg"]] + lengths[Joint[s + "Foot"]] for s in _SIDES]))
