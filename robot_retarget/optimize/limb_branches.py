"""Start a sequence in each limb's best branch: a multi-start of the first frame.

A warm-started solve follows the local minimum it starts in. A limb with fewer joints than its
bones' directions need has several: OP3's 3-joint arm (no upper-arm twist, an elbow that bends
both ways) can bend its elbow either way and trade the upper arm's direction against the
forearm's. Measured on OP3 with ideal targets (``--model oracle``, CMU subjects 02, 05, 13, every
evaluation frame solved to its optimum without the velocity limit): the arm optimum reached from
the kinematic limit's pose had the lower cost in 60–66 % of frames, and picking the lower-cost
optimum per frame brought the arms' mean direction error from 26.4° / 24.3° (left / right) to
21.1° / 18.3° (the limit: 20.1° / 17.4°).

A sequence keeps the branch it starts in for long, so :meth:`Retargeter.settle` (the first frame
of every conversion and stream) solves each limb — a group of ≥ 2 bones that share joints — from
its current optimum, with its joints at zero and with its joints negated, the others held, and
keeps the best. Mean direction error of eval-robot's pipeline on OP3 (shipped network), without →
with: CMU 02/05/13 (tuning) 14.85° → 14.02°, 06/08/12 11.68° → 12.16°, 03/07/10/14 15.62° →
13.42° (ideal targets, 02/05/13: 14.15° → 13.37°); Poppy 5.14° → 4.85°, 3.75° → 3.56°,
3.70° → 3.70°. Most of it is decided on the DAZ clips, which begin in a T-pose: a straight arm
along OP3's shoulder-pitch axis can take any pitch, the two optima (pitch ≈ ±80°, 2.8 rad apart)
differ in cost by 0.015, and which one serves the rest of the clip better is a coin toss: the
multi-start's was better in 3 of 14 such clips, by 10–28° of arm error (where the other branch
ends at ≈ 50°), worse in 11 by 3–10°. Keeping the branch reached from the init pose unless
another is better by a margin (0.02–0.1) gave 14.79° / 11.68° / 15.62°.

Switching branches *during* a sequence did not pay: probing one limb every 4 or 12 frames and,
when another branch was better by a margin, pulling the limb there with a pose term (at the
servos' speed) raised the error to 13.5–14.6° for every margin (0.05–0.5) and pull (1–10) tried.
The two optima of OP3's arm lie > 0.6 rad apart, so a switch takes ≥ 0.15 s at full speed and
swings the arm through 75–115° of error; boxing alternates the better branch with every punch.
"""

from __future__ import annotations

import math

import numpy as np

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.optimize.objective import ParameterWriter
from robot_retarget.optimize.solver import BufferedSolver

_CONSTRAINT_TOL = 1e-6
# The solves' time step (s): smoothing terms (∝ 1/dt², 1/dt⁴) vanish, as in Retargeter.settle.
_STATIC_DT_S = 1e3


class LimbBranches:
    """Multi-start solves of single limbs, on a solver of its own (the online solver's twin)."""

    def __init__(
        self,
        solver: BufferedSolver,
        writer: ParameterWriter,
        limbs: tuple[IntArray, ...],
        lower: FloatArray,
        upper: FloatArray,
    ) -> None:
        self._s = solver
        self._writer = writer
        self.limbs = limbs  # joint indices of each limb
        self.lower = lower
        self.upper = upper

    def optimum(
        self, source: BufferedSolver, q: FloatArray, joints: IntArray, start: FloatArray
    ) -> tuple[FloatArray, float]:
        """The optimum of ``source``'s current problem (its targets and constraint bounds)
        reached from ``start``, with only ``joints`` free (the others held at ``q``) and no
        velocity limit: (pose, cost); cost ∞ when the solve fails."""
        s = self._s
        s.p[:] = source.p
        s.lbg[:] = source.lbg
        s.ubg[:] = source.ubg
        self._writer.write_history(q, q, _STATIC_DT_S)
        s.lbx[:] = q
        s.ubx[:] = q
        s.lbx[joints] = self.lower[joints]
        s.ubx[joints] = self.upper[joints]
        np.clip(start, s.lbx, s.ubx, out=s.x0)
        s.lam_x0[:] = 0.0
        s.lam_g0[:] = 0.0
        s.call()
        x = s.x
        if not np.all(np.isfinite(x)):
            return q, math.inf
        g = s.g
        if g.size and max(float((s.lbg - g).max()), float((g - s.ubg).max())) > _CONSTRAINT_TOL:
            return q, math.inf
        return np.clip(x, s.lbx, s.ubx), float(s.f[0])

    NUM_STARTS = 3  # what starts() returns, in this order (a whole-clip choice indexes them)

    @staticmethod
    def starts(q: FloatArray, joints: IntArray) -> list[FloatArray]:
        """A limb's :data:`NUM_STARTS` starts: ``q``, and its joints at zero and negated
        (clipped by :meth:`optimum`)."""
        zero = q.copy()
        zero[joints] = 0.0
        neg = q.copy()
        neg[joints] = -q[joints]
        return [q, zero, neg]

    def best(
        self, source: BufferedSolver, q: FloatArray, choice: tuple[int | None, ...] | None = None
    ) -> tuple[FloatArray, float]:
        """Every limb in turn from its best start, the other joints held: (pose, cost).
        ``choice``: per limb, the index of the start (in :meth:`starts`) whose optimum it takes
        instead of the best (the best where that solve failed)."""
        out = q.copy()
        cost = math.inf
        for k, joints in enumerate(self.limbs):
            results = [self.optimum(source, out, joints, s) for s in self.starts(out, joints)]
            pick = min(results, key=lambda r: r[1])
            chosen = None if choice is None else choice[k]
            if chosen is not None and math.isfinite(results[chosen][1]):
                pick = results[chosen]
            out, cost = pick
        return out, cost
