"""End effectors: ``w · Σ_ee w_ee |p_e(q) − p*_e|²`` on hand / foot / head positions (m, root
frame). Off (weight 0) in frames whose targets carry none; a robot that maps no end effector has
no parameters and no residual here."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SolveError
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.targets import FrameTargets, check_array
from robot_retarget.optimize.terms.term import CostTerm, TermContext, weighted_blocks


@dataclass(frozen=True)
class EndEffectorTerm(CostTerm):
    """Per frame: target positions (E·3) and weights (E) = ``weight`` × the targets' own."""

    name = "end_effector"
    num_ee: int
    weight: float
    robot: str  # for the error when a robot without end effectors is given targets

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("target", 3 * self.num_ee), Parameter("weight", self.num_ee))

    def residual(self, ctx: TermContext) -> ca.SX:
        if not self.num_ee:
            return ca.SX(0, 1)
        p = ctx.params
        return weighted_blocks(ctx.robot.ee_positions - p["target"], p["weight"], 3)

    def write_frame(self, params: Mapping[str, FloatArray], targets: FrameTargets) -> None:
        ne = self.num_ee
        if not ne:
            if targets.ee_positions is not None and np.size(targets.ee_positions):
                raise SolveError(
                    f"robot {self.robot} maps no end effectors, but targets were given"
                )
            return
        if targets.ee_positions is None:
            params["weight"][:] = 0.0
            return
        params["target"][:] = check_array(
            "end-effector targets", targets.ee_positions, (ne, 3)
        ).ravel()
        w = (
            np.ones(ne)
            if targets.ee_weights is None
            else check_array("end-effector weights", targets.ee_weights, (ne,))
        )
        params["weight"][:] = self.weight * w
