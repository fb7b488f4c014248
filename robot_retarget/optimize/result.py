"""What one solve returns: the command and how it was obtained."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from robot_retarget.array_types import FloatArray


class SolveStatus(str, Enum):
    """How the command in a SolveResult came about."""

    OPTIMAL = "optimal"  # the solver converged; output checked against every hard limit
    MAX_ITER = "max_iter"  # iteration cap hit; the (feasible, clipped) iterate is used
    # Stopped at the step tolerance (settings.step_tol_ticks): the next step would move no
    # joint by more than a fraction of a servo tick; checked against every hard limit.
    STEP_TOL = "step_tol"
    FALLBACK = "fallback"  # the solver failed; projection of the previous command is used


@dataclass(frozen=True)
class SolveResult:
    """One frame's command (online) or one clip's commands (offline).

    ``q`` is (J,) rad for a frame, (T, J) for a clip; it is always inside the joint limits and
    the velocity box around the previous command (or moving toward the limits at ≤ v_max when
    the previous command was outside them). ``max_violation`` is the largest violation of the
    *solver's* constraints (twist bound, ground, rad or m) before clipping: 0 when satisfied.
    ``iterations`` is the SQP's iteration count; None for an online frame that converged to
    the KKT tolerances (OPTIMAL: the live path does not read casadi's statistics for it, 15–50
    µs per frame; right after a solve, ``Retargeter.online_solver.last_status()`` reads them).
    A frame stopped at the step tolerance (STEP_TOL) or the cap reports its count.
    """

    status: SolveStatus
    q: FloatArray = field(repr=False)
    cost: float
    iterations: int | None
    solve_time_s: float
    max_violation: float
    used_fallback: bool
    message: str = ""

    @property
    def ok(self) -> bool:
        """Converged: to the KKT tolerances, or to the step tolerance (finer than a tick)."""
        return self.status in (SolveStatus.OPTIMAL, SolveStatus.STEP_TOL)
