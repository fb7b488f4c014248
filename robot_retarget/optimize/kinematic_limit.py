"""The kinematic limit: per frame, the least segment-direction error the robot can reach.

For target segment directions (unit, in a body frame rigid in the robot's root), find joint
angles within the joint limits that minimise the mean angle between robot and target segments —
no speed limit, no smoothness, no twist bound: the best score any retargeter could reach on this
robot, frame by frame. The problem is non-convex (an arm can bend either way), so it is solved
from several starts: the caller's candidates (e.g. the pipeline's and a baseline's solutions,
which makes the limit never worse than them), the init and zero poses, and seeded random poses.

Segments that depend on disjoint sets of joints (the limbs) are independent, so the best start is
chosen per group of coupled segments and the groups' joints are combined: the minimum of the sum
is the sum of the group minima. Each start is solved on the squared chords |d − t|² = 2 − 2cos θ
(smooth, ≈ 0.7 ms per SQP solve); the best combination is then polished on the angle itself by
iteratively reweighted least squares (weights dθ/dc / 2c, 4 rounds), and every candidate —
unsolved starts included — is scored with the exact angle ``atan2(|a×b|, a·b)``.

Measured on OP3 (5 groups: two arms, two legs, the rigid trunk), 4 random starts: ≈ 2–3 ms per
frame without the caller's candidates; reachable targets are matched to < 1e-9 rad.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SolveError
from robot_retarget.optimize.chains import SegmentFrames, coupled_groups
from robot_retarget.optimize.solver import BufferedSolver, SolverSpec, build_solver
from robot_retarget.optimize.symbolic_kinematics import SymbolicKinematics
from robot_retarget.robot.config import RobotConfig

_NORM_EPS = 1e-12  # keeps the segment-length sqrt differentiable
_MAX_ITER = 40
_IRLS_ROUNDS = 4
_CHORD_FLOOR = 1e-6  # chord below which a segment counts as matched (IRLS weight cap)


def _irls_weights(theta: FloatArray) -> FloatArray:
    """Weights w with ∇Σ w·c² ∝ ∇Σ θ at the current point: θ = 2·asin(c/2) for the chord
    c = |d − t|, so dθ/dc = 1/√(1 − c²/4) and w = (dθ/dc) / (2c)."""
    c = np.maximum(2.0 * np.sin(0.5 * theta), _CHORD_FLOOR)
    w = 1.0 / (2.0 * c * np.sqrt(np.maximum(1.0 - 0.25 * c * c, 1e-12)))
    return np.asarray(w / np.max(w), dtype=np.float64)


@dataclass(frozen=True)
class LimitResult:
    """Per frame: the best joint angles (T, J), their segment angles (T, S) in rad, and which
    candidate each coupled group took (T, G): an index into the K starts (the caller's first,
    then init, zero, random), ``K + k`` for start k after solving, ``2K`` for the polished
    combination."""

    q: FloatArray
    angles: FloatArray
    choice: npt.NDArray[np.int64]
    solve_time_s: float
    solves: int


class KinematicLimit:
    """Multi-start minimiser of the mean segment-direction angle within the joint limits.

    ``body_axes`` (3, 3): rows forward, left, up of the body frame in the root frame (the frame
    the targets are given in). ``random_starts`` poses are drawn uniformly within the limits
    with ``seed``.
    """

    def __init__(
        self,
        config: RobotConfig,
        segments: Sequence[SegmentFrames],
        body_axes: npt.ArrayLike,
        *,
        random_starts: int = 4,
        seed: int = 0,
        jit: bool = True,
        cache_dir: str | Path | None = None,
    ) -> None:
        if not segments:
            raise SolveError("the kinematic limit needs at least one segment to score")
        self.config = config
        self.num_segments = len(segments)
        self.lower = config.lower
        self.upper = config.upper
        axes = np.asarray(body_axes, dtype=np.float64)
        if axes.shape != (3, 3):
            raise SolveError(f"body_axes must be (3, 3), got {axes.shape}")
        q = ca.SX.sym("q", config.num_joints)
        kin = SymbolicKinematics(config, q)
        n = self.num_segments
        target = ca.SX.sym("target", 3 * n)
        weight = ca.SX.sym("weight", n)
        chords, exact = [], []
        for k, (starts, ends) in enumerate(segments):
            a = sum((kin.position(f) for f in starts), ca.SX.zeros(3, 1)) / len(starts)
            b = sum((kin.position(f) for f in ends), ca.SX.zeros(3, 1)) / len(ends)
            d = ca.SX(axes) @ (b - a)
            t = target[3 * k : 3 * k + 3]
            chords.append(d / ca.sqrt(ca.sumsqr(d) + _NORM_EPS) - t)
            exact.append(ca.atan2(ca.norm_2(ca.cross(d, t)), ca.dot(d, t)))
        r = ca.vertcat(*(ca.sqrt(weight[k]) * c for k, c in enumerate(chords)))
        nlp = {
            "x": q,
            "p": ca.vertcat(target, weight),
            "f": ca.sumsqr(r),
            "g": ca.SX(0, 1),
            "r": r,
        }
        spec = SolverSpec(
            name=f"kinematic_limit_{config.name}_{n}".replace("-", "_"),
            qpsol="daqp",
            hessian="exact",
            max_iter=_MAX_ITER,
            tol_pr=1e-9,
            tol_du=1e-10,
            jit=jit,
            cache_dir=None if cache_dir is None else Path(cache_dir),
        )
        solver, jit_used = build_solver(spec, nlp)
        self._solver = BufferedSolver(solver, jit_used)
        self._angles = ca.Function("segment_angles", [q, target], [ca.vertcat(*exact)])
        self.groups, self.group_joints = coupled_groups(config, segments)
        self._rng_seed = seed
        self.random_starts = random_starts

    def segment_angles(self, q: npt.ArrayLike, targets: npt.ArrayLike) -> FloatArray:
        """(S,) exact angles (rad) of joint angles ``q`` (J,) against targets (S, 3)."""
        t = np.asarray(targets, dtype=np.float64).ravel()
        return np.asarray(self._angles(np.asarray(q, dtype=np.float64), t)).ravel()

    def _run(self, x0: FloatArray) -> tuple[FloatArray, float]:
        """One solve from ``x0``; the result clipped into the limits (``x0`` if not finite)."""
        s = self._solver
        s.x0[:] = x0
        s.lam_x0[:] = 0.0
        t0 = time.perf_counter()
        s.call()
        elapsed = time.perf_counter() - t0
        x = s.x.copy()
        if not np.all(np.isfinite(x)):
            return x0.copy(), elapsed
        return np.clip(x, self.lower, self.upper), elapsed

    def _angles_of(self, cands: FloatArray, target: FloatArray) -> FloatArray:
        """(K, S) exact angles of candidate poses (K, J)."""
        fn = self._angles.map(cands.shape[0])
        return np.asarray(fn(cands.T, target)).T

    def _combine(
        self,
        base: FloatArray,
        cands: FloatArray,
        ang: FloatArray,
        choice: npt.NDArray[np.int64] | None = None,
    ) -> FloatArray:
        """Per coupled group, the joints of the candidate with the least summed angle."""
        q = base.copy()
        for g, (segs, joints) in enumerate(zip(self.groups, self.group_joints, strict=True)):
            best = int(np.argmin(ang[:, segs].sum(axis=1)))
            if choice is not None:
                choice[g] = best
            q[joints] = cands[best, joints]
        return q

    def _starts(self, frames: int) -> FloatArray:
        """(T, 2 + R, J): init, zero (clipped) and R random poses per frame, seeded."""
        rng = np.random.default_rng(self._rng_seed)
        lo, hi = self.lower, self.upper
        fixed = np.stack([self.config.init_pose, np.zeros_like(lo)])
        fixed = np.clip(fixed, lo, hi)
        rand = rng.uniform(lo, hi, size=(frames, self.random_starts, lo.size))
        return np.concatenate([np.broadcast_to(fixed, (frames, 2, lo.size)), rand], axis=1)

    def solve(self, targets: npt.ArrayLike, candidates: npt.ArrayLike | None = None) -> LimitResult:
        """Targets (T, S, 3) unit directions in the body frame; ``candidates`` (T, K, J) extra
        starts per frame (e.g. other retargeters' solutions), clipped into the limits."""
        tg = np.asarray(targets, dtype=np.float64)
        if tg.ndim != 3 or tg.shape[1:] != (self.num_segments, 3):
            raise SolveError(f"targets must be (T, {self.num_segments}, 3), got {tg.shape}")
        if not np.all(np.isfinite(tg)):
            raise SolveError("kinematic-limit targets contain NaN or infinite values")
        frames = tg.shape[0]
        j = self.config.num_joints
        extra = np.zeros((frames, 0, j))
        if candidates is not None:
            extra = np.asarray(candidates, dtype=np.float64)
            if extra.ndim != 3 or extra.shape[0] != frames or extra.shape[2] != j:
                raise SolveError(f"candidates must be (T={frames}, K, J={j}), got {extra.shape}")
        starts = np.clip(
            np.concatenate([extra, self._starts(frames)], axis=1), self.lower, self.upper
        )
        n_starts = starts.shape[1]
        s = self._solver
        s.lbx[:] = self.lower
        s.ubx[:] = self.upper
        n = self.num_segments
        q_out = np.empty((frames, j))
        ang_out = np.empty((frames, n))
        choice = np.empty((frames, len(self.groups)), dtype=np.int64)
        solve_time = 0.0
        solves = 0
        for t in range(frames):
            target = tg[t].ravel()
            s.p[: 3 * n] = target
            s.p[3 * n :] = 1.0
            cands = [starts[t, k] for k in range(n_starts)]
            for k in range(n_starts):
                x, dt = self._run(starts[t, k])
                cands.append(x)
                solve_time += dt
            # Polish the best chord solution (per group) on the angle itself (IRLS).
            c = np.stack(cands)
            ang = self._angles_of(c, target)
            q = self._combine(starts[t, 0], c, ang)
            for _ in range(_IRLS_ROUNDS):
                theta = self.segment_angles(q, tg[t])
                s.p[3 * n :] = _irls_weights(theta)
                x, dt = self._run(q)
                solve_time += dt
                q = x
            cands.append(q)
            c = np.stack(cands)
            ang = self._angles_of(c, target)
            solves += n_starts + _IRLS_ROUNDS
            best = self._combine(starts[t, 0], c, ang, choice[t])
            q_out[t] = best
            ang_out[t] = self.segment_angles(best, tg[t])
        return LimitResult(q_out, ang_out, choice, solve_time, solves)


__all__ = ["KinematicLimit", "LimitResult", "SegmentFrames"]
