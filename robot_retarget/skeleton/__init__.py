"""Skeletons (joint trees with rest offsets), forward kinematics and the canonical human."""

from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    REQUIRED_JOINTS,
    Joint,
    default_canonical_skeleton,
)
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics, local_from_global

__all__ = [
    "CANONICAL_JOINTS",
    "CANONICAL_PARENTS",
    "REQUIRED_JOINTS",
    "Joint",
    "Skeleton",
    "default_canonical_skeleton",
    "forward_kinematics",
    "local_from_global",
]
