"""The online solve's iterate checked and projected in one compiled call.

After each online SQP solve, :meth:`robot_retarget.optimize.retargeter.Retargeter` asks three
things of the iterate ``x``: is it (and the constraint values ``g``) finite, how far does it
violate ``lbg ≤ g ≤ ubg``, and where does it land once projected onto the frame's box
``[lbx, ubx]``. In numpy that is five calls of a few microseconds each on arrays of twenty
numbers; here it is one SX function bound to the solver's own arrays. (The projected command is
still checked against its box in numpy afterwards: a servo is on the other side. The projection
keeps a NaN a NaN, so that check would see one even if the finiteness flag missed it.)
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction, compile_graph
from robot_retarget.optimize.solver import BufferedSolver


def _check_graph(nx: int, ng: int) -> tuple[list[ca.SX], list[ca.SX]]:
    """``(x, g, lbg, ubg, lbx, ubx) → (q, nonfinite, violation)``."""
    x, lbx, ubx = (ca.SX.sym(n, nx) for n in ("x", "lbx", "ubx"))
    g, lbg, ubg = (ca.SX.sym(n, ng) for n in ("g", "lbg", "ubg"))
    # |v| < inf is false for ±inf and for NaN (every comparison with NaN is).
    nonfinite = ca.sum1(ca.if_else(ca.fabs(ca.vertcat(x, g)) < ca.inf, 0.0, 1.0))
    violation = ca.mmax(ca.vertcat(lbg - g, g - ubg, ca.SX(0.0)))
    # Not fmin/fmax, which drop a NaN: a NaN iterate stays NaN, for the numpy check after.
    q = ca.if_else(x < lbx, lbx, ca.if_else(x > ubx, ubx, x))
    return [x, g, lbg, ubg, lbx, ubx], [q, nonfinite, violation]


class OnlineCheck:
    """Bound to an online solver's arrays: call after a solve, then read :attr:`q` (the
    iterate projected onto the box; meaningful only when finite)."""

    def __init__(
        self, solver: BufferedSolver, *, jit: bool = True, cache_dir: Path | None = None
    ) -> None:
        nx, ng = solver.x.size, solver.g.size
        fn = compile_graph("online_check", *_check_graph(nx, ng), jit=jit, cache_dir=cache_dir)
        s = solver
        self._fn = CompiledFunction(fn, args=[s.x, s.g, s.lbg, s.ubg, s.lbx, s.ubx])
        self.q: FloatArray = self._fn.res[0]
        self._nonfinite, self._violation = self._fn.res[1], self._fn.res[2]

    def __call__(self) -> tuple[bool, float]:
        """(x and g finite, the largest constraint violation, 0 when none)."""
        self._fn()
        return bool(self._nonfinite[0] == 0.0), float(self._violation[0])
