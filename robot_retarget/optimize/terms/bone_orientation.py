"""Bone roll: ``w · Σ_bones |n_b(q) − n*_b|²`` on a unit normal of each bone (root frame).

Off (weight 0) in frames whose targets carry no normals.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.targets import FrameTargets, check_array
from robot_retarget.optimize.terms.term import CostTerm, TermContext, weighted_blocks


@dataclass(frozen=True, eq=False)  # holds an array
class BoneOrientationTerm(CostTerm):
    """Per frame: target normals (B·3) and per-bone weights (B): ``weights``, or 0 without
    normals."""

    name = "bone_orientation"
    weights: FloatArray  # (B,)

    @property
    def num_bones(self) -> int:
        return int(self.weights.size)

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("target", 3 * self.num_bones), Parameter("weight", self.num_bones))

    def residual(self, ctx: TermContext) -> ca.SX:
        p = ctx.params
        return weighted_blocks(ctx.robot.bone_normals - p["target"], p["weight"], 3)

    def write_frame(self, params: Mapping[str, FloatArray], targets: FrameTargets) -> None:
        if targets.normals is None:
            params["weight"][:] = 0.0
            return
        params["target"][:] = check_array(
            "target normals", targets.normals, (self.num_bones, 3)
        ).ravel()
        params["weight"][:] = self.weights
