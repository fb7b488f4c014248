"""Velocity smoothness: ``w · |(q_t − q_{t−1}) / dt|²`` ((rad/s)²)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.terms.term import CostTerm, TermContext


@dataclass(frozen=True)
class VelocityTerm(CostTerm):
    """Shared: the weight (s²/rad²)."""

    name = "velocity"
    weight: float

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("weight", 1, shared=True),)

    def residual(self, ctx: TermContext) -> ca.SX:
        return ca.sqrt(ctx.params["weight"]) * ctx.inv_dt * (ctx.q - ctx.q_prev)

    def init_shared(self, params: Mapping[str, FloatArray]) -> None:
        params["weight"][:] = self.weight
