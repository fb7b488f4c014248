"""Bone directions on unit vectors in the root frame, per bone b with chord c_b = |d_b(q) − d*_b|:

- ``eps = 0``: ``Σ_b w_b · c_b²`` (squared chords);
- ``eps > 0``: ``Σ_b w_b · (√(c_b² + eps²) − eps)`` — pseudo-Huber: squared below ``eps``,
  linear above. The score is the mean *angle* (θ = 2·asin(c/2) ≈ c), which squared chords
  overweight where a limb cannot match both of its bones (OP3's 3-joint arm): they split the
  error evenly, where the least mean angle matches one bone and leaves the other.

As a residual: ``r_b = √w_b · (d_b − d*_b) / √(√(c_b² + eps²) + eps)``, whose square is the
pseudo-Huber cost exactly and which is smooth at c = 0.
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
class BoneDirectionTerm(CostTerm):
    """Per frame: target directions (B·3) and per-bone weights (B, constant: ``weights``)."""

    name = "bone_direction"
    weights: FloatArray  # (B,)
    eps: float = 0.0  # pseudo-Huber scale (chord); 0: squared chords

    @property
    def num_bones(self) -> int:
        return int(self.weights.size)

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("target", 3 * self.num_bones), Parameter("weight", self.num_bones))

    def residual(self, ctx: TermContext) -> ca.SX:
        p = ctx.params
        diff = ctx.robot.bone_directions - p["target"]
        if self.eps > 0.0:
            nb = self.num_bones
            c2 = ca.sum1(ca.reshape(diff, 3, nb) ** 2)  # (1, B) squared chords
            scale = 1.0 / ca.sqrt(ca.sqrt(c2 + self.eps**2) + self.eps)
            diff = diff * ca.repmat(scale, 3, 1).reshape((-1, 1))
        return weighted_blocks(diff, p["weight"], 3)

    def init_frame(self, params: Mapping[str, FloatArray]) -> None:
        params["weight"][:] = self.weights

    def write_frame(self, params: Mapping[str, FloatArray], targets: FrameTargets) -> None:
        params["target"][:] = check_array(
            "target directions", targets.directions, (self.num_bones, 3)
        ).ravel()
