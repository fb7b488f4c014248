"""A small dense box-constrained QP, ``min ½ xᵀHx + cᵀx  s.t.  lo ≤ x ≤ hi`` (numpy).

Primal active set (Nocedal & Wright §16.5) on bounds only: H positive definite, a feasible start
(0 when lo ≤ 0 ≤ hi, else the projection of 0). Each step solves the free variables' system with
the fixed ones at their bounds; a blocked step fixes the first bound it meets, a full step frees
the fixed variable whose multiplier has the wrong sign. Exact after finitely many steps; the
differential IK of :mod:`.gmr_style` (≤ 20 variables) needs a handful.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import FloatArray

_TOL = 1e-12


def box_qp(
    h: FloatArray, c: FloatArray, lo: FloatArray, hi: FloatArray, max_steps: int | None = None
) -> FloatArray:
    """The minimiser of ``½ xᵀHx + cᵀx`` over the box (H symmetric positive definite)."""
    n = c.size
    if np.any(lo > hi):
        raise ValueError("box_qp: a lower bound exceeds its upper bound")
    x = np.clip(np.zeros(n), lo, hi)
    at_lo = x <= lo
    at_hi = (x >= hi) & ~at_lo
    for _ in range(max_steps or 4 * n + 10):
        free = ~(at_lo | at_hi)
        target = x.copy()
        if free.any():
            rhs = -(c[free] + h[np.ix_(free, ~free)] @ x[~free])
            target[free] = np.linalg.solve(h[np.ix_(free, free)], rhs)
        d = target - x
        # Largest step in [0, 1] that keeps the free variables inside the box.
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(d < -_TOL, (lo - x) / d, np.where(d > _TOL, (hi - x) / d, np.inf))
        ratio[~free] = np.inf
        k = int(np.argmin(ratio))
        if ratio[k] < 1.0:
            x = x + max(ratio[k], 0.0) * d
            if d[k] < 0.0:
                x[k], at_lo[k] = lo[k], True
            else:
                x[k], at_hi[k] = hi[k], True
            continue
        x = target
        g = h @ x + c  # multipliers of the fixed bounds: ≥ 0 at lo, ≤ 0 at hi when optimal
        wrong = np.where(at_lo, -g, np.where(at_hi, g, 0.0))
        k = int(np.argmax(wrong))
        if wrong[k] <= _TOL * (1.0 + float(np.abs(g).max())):
            return np.clip(x, lo, hi)
        at_lo[k] = at_hi[k] = False
    return np.clip(x, lo, hi)
