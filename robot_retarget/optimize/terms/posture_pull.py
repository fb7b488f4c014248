"""A weak pull toward a rest posture: ``w · |q_t − q_pose|²`` (rad²). It settles joints no
other term constrains and breaks ties between equal solutions."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.terms.term import CostTerm, TermContext


@dataclass(frozen=True, eq=False)  # holds an array
class PosturePullTerm(CostTerm):
    """Shared: the posture (J) and the weight (1/rad²)."""

    name = "posture"
    pose: FloatArray
    weight: float

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter("pose", int(self.pose.size), shared=True),
            Parameter("weight", 1, shared=True),
        )

    def residual(self, ctx: TermContext) -> ca.SX:
        return ca.sqrt(ctx.params["weight"]) * (ctx.q - ctx.params["pose"])

    def init_shared(self, params: Mapping[str, FloatArray]) -> None:
        params["pose"][:] = self.pose
        params["weight"][:] = self.weight
