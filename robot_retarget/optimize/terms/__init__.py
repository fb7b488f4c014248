"""The optimizer's cost terms, one per module (see :mod:`.term` for what a term is)."""

from __future__ import annotations

from robot_retarget.optimize.terms.acceleration import AccelerationTerm
from robot_retarget.optimize.terms.bone_direction import BoneDirectionTerm
from robot_retarget.optimize.terms.bone_orientation import BoneOrientationTerm
from robot_retarget.optimize.terms.end_effector import EndEffectorTerm
from robot_retarget.optimize.terms.keypoint import KeypointTerm
from robot_retarget.optimize.terms.posture_pull import PosturePullTerm
from robot_retarget.optimize.terms.term import CostTerm, TermContext, weighted_blocks
from robot_retarget.optimize.terms.velocity import VelocityTerm

__all__ = [
    "AccelerationTerm",
    "BoneDirectionTerm",
    "BoneOrientationTerm",
    "CostTerm",
    "EndEffectorTerm",
    "KeypointTerm",
    "PosturePullTerm",
    "TermContext",
    "VelocityTerm",
    "weighted_blocks",
]
