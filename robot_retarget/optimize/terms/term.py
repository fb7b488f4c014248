"""What a cost term is: named parameters, a weighted residual, and how its parameters are filled.

The objective of every frame is ``Σ_terms |r_term|²``; each term returns its residual already
scaled by √weight, so the sum of squares is the cost and ``2·JᵀJ`` of the stacked residuals is
the Gauss–Newton Hessian the offline windows use. Weights are parameters, not constants: one
compiled solver serves every weight setting.

A term declares its parameters by local name (``"target"``, ``"weight"``); the objective
prefixes them with the term's name and lays them out once (:mod:`..parameter_layout`). The
builder hands :meth:`CostTerm.residual` the symbolic parameters, the Retargeter hands the
``write_*`` methods numpy views of the same slices.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.formulation import FrameQuantities
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.targets import FrameTargets


@dataclass(frozen=True)
class TermContext:
    """Everything a term's residual of frame t may depend on (CasADi SX)."""

    q: ca.SX  # (J,) joint angles of frame t
    q_prev: ca.SX  # (J,) frame t−1: the committed history or the window's previous frame
    q_prev2: ca.SX  # (J,) frame t−2
    inv_dt: ca.SX  # 1/dt (1/s)
    robot: FrameQuantities  # forward kinematics at q
    params: Mapping[str, ca.SX]  # this term's parameters by local name (frame t's and shared)


class CostTerm(ABC):
    """One named term of the per-frame cost."""

    name: ClassVar[str]

    @abstractmethod
    def parameters(self) -> tuple[Parameter, ...]:
        """The term's parameters (local names; ``shared=True``: once per window)."""

    @abstractmethod
    def residual(self, ctx: TermContext) -> ca.SX:
        """Weighted residual of frame t: its squared norm is the term's cost."""

    def init_shared(self, params: Mapping[str, FloatArray]) -> None:  # noqa: B027  # optional hook
        """Write constant shared parameters (once per solver)."""

    def init_frame(self, params: Mapping[str, FloatArray]) -> None:  # noqa: B027  # optional hook
        """Write constant per-frame parameters of one frame block (once per solver)."""

    def write_frame(self, params: Mapping[str, FloatArray], targets: FrameTargets) -> None:  # noqa: B027
        """Validate one frame's targets and write this term's part of them."""


def weighted_blocks(residual: ca.SX, weights: ca.SX, block: int) -> ca.SX:
    """Residual blocks scaled by √weight, so that |out|² = Σ_k weights[k] · |block k|²."""
    scale = ca.repmat(ca.sqrt(weights).T, block, 1).reshape((-1, 1))
    return residual * scale
