"""Acceleration smoothness: ``w · |(q_t − 2 q_{t−1} + q_{t−2}) / dt²|²`` ((rad/s²)²)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.terms.term import CostTerm, TermContext


@dataclass(frozen=True)
class AccelerationTerm(CostTerm):
    """Shared: the weight (s⁴/rad²)."""

    name = "acceleration"
    weight: float

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("weight", 1, shared=True),)

    def residual(self, ctx: TermContext) -> ca.SX:
        second = ctx.q - 2.0 * ctx.q_prev + ctx.q_prev2
        return ca.sqrt(ctx.params["weight"]) * ctx.inv_dt * ctx.inv_dt * second

    def init_shared(self, params: Mapping[str, FloatArray]) -> None:
        params["weight"][:] = self.weight
