"""A per-frame position-IK baseline: robot points (elbows, hands, knees, feet) to 3D targets.

The way most people retarget today (e.g. GMR-style pipelines): scale the human's keypoints to
the robot's limb lengths, then solve inverse kinematics frame by frame for joint angles within
the joint limits and the velocity box around the previous frame. Cost per frame:

    Σ_k w_k |p_k(q) − p*_k|²  +  w_damping |q − q_prev|²

(m² and rad²); the damping term settles joints no target constrains (head, ankles) and breaks ties
between equal solutions. Built on the optimizer's symbolic kinematics and solver utilities
(sqpmethod, exact Hessian convexified, daqp, JIT-cached); each result is clipped into the box.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SolveError
from robot_retarget.optimize.limits import velocity_box
from robot_retarget.optimize.solver import BufferedSolver, SolverSpec, build_solver
from robot_retarget.optimize.symbolic_kinematics import SymbolicKinematics
from robot_retarget.robot.config import RobotConfig

_MAX_ITER = 20


@dataclass(frozen=True)
class PositionIKResult:
    """A solved clip: ``q`` (T, J) rad inside the limits and velocity box, the frames whose
    solve failed (the projected previous pose was used), solver seconds."""

    q: FloatArray
    fallbacks: int
    solve_time_s: float


class PositionIK:
    """Per-frame IK of named robot frames to position targets (root frame, metres)."""

    def __init__(
        self,
        config: RobotConfig,
        points: Sequence[str],
        *,
        weights: Sequence[float] | None = None,
        w_damping: float = 1e-4,
        jit: bool = True,
        cache_dir: str | Path | None = None,
    ) -> None:
        if not points:
            raise SolveError("position IK needs at least one target frame")
        w = np.ones(len(points)) if weights is None else np.asarray(weights, dtype=np.float64)
        if w.shape != (len(points),) or np.any(w < 0.0) or not np.all(np.isfinite(w)):
            raise SolveError(
                f"weights must be {len(points)} finite numbers ≥ 0 (one per point), got {w}"
            )
        if not (math.isfinite(w_damping) and w_damping >= 0.0):
            raise SolveError(f"w_damping must be finite and ≥ 0, got {w_damping}")
        self.config = config
        self.points = tuple(points)
        self.num_joints = config.num_joints
        q = ca.SX.sym("q", self.num_joints)
        kin = SymbolicKinematics(config, q)
        n = len(self.points)
        target = ca.SX.sym("target", 3 * n)
        q_prev = ca.SX.sym("q_prev", self.num_joints)
        res = [
            math.sqrt(float(w[k])) * (kin.position(f) - target[3 * k : 3 * k + 3])
            for k, f in enumerate(self.points)
        ]
        res.append(math.sqrt(w_damping) * (q - q_prev))
        r = ca.vertcat(*res)
        nlp = {"x": q, "p": ca.vertcat(target, q_prev), "f": ca.sumsqr(r), "g": ca.SX(0, 1), "r": r}
        spec = SolverSpec(
            name=f"position_ik_{config.name}_{n}".replace("-", "_"),
            qpsol="daqp",
            hessian="exact",
            max_iter=_MAX_ITER,
            jit=jit,
            cache_dir=None if cache_dir is None else Path(cache_dir),
        )
        solver, jit_used = build_solver(spec, nlp)
        self._solver = BufferedSolver(solver, jit_used)
        self._positions = kin.positions_function(self.points)
        self.reset()

    def positions(self, q: npt.ArrayLike) -> FloatArray:
        """(P, 3) positions (m, root frame) of the target frames at ``q`` (J,)."""
        return np.asarray(self._positions(np.asarray(q, dtype=np.float64))).T.copy()

    def reset(self, q: npt.ArrayLike | None = None) -> None:
        """Start a new sequence at ``q`` (default: the init pose)."""
        start = self.config.init_pose if q is None else q
        self._q_prev = np.asarray(start, dtype=np.float64).copy()
        if self._q_prev.shape != (self.num_joints,):
            raise SolveError(f"start pose must have shape ({self.num_joints},)")

    def solve(self, targets: npt.ArrayLike, dt_s: float) -> tuple[FloatArray, bool]:
        """One frame: (q (J,), solved) — ``solved`` False when the projected previous pose
        was used because the solver returned no finite point."""
        tg = np.asarray(targets, dtype=np.float64)
        if tg.shape != (len(self.points), 3) or not np.all(np.isfinite(tg)):
            raise SolveError(
                f"targets must be finite, shape ({len(self.points)}, 3), got {tg.shape}"
            )
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise SolveError(f"dt_s must be a finite positive number of seconds, got {dt_s}")
        cfg = self.config
        lo, hi = velocity_box(self._q_prev, cfg.lower, cfg.upper, cfg.max_velocity * dt_s)
        s = self._solver
        s.lbx[:] = lo
        s.ubx[:] = hi
        s.p[: tg.size] = tg.ravel()
        s.p[tg.size :] = self._q_prev
        s.x0[:] = np.clip(self._q_prev, lo, hi)
        s.lam_x0[:] = 0.0
        s.call()
        ok = bool(np.all(np.isfinite(s.x)))
        q = np.clip(s.x if ok else self._q_prev, lo, hi)
        self._q_prev = q
        return q.copy(), ok

    def solve_clip(
        self, targets: npt.ArrayLike, dt_s: float, q_start: npt.ArrayLike | None = None
    ) -> PositionIKResult:
        """Targets (T, P, 3), frame by frame from ``q_start`` (default: the init pose)."""
        tg = np.asarray(targets, dtype=np.float64)
        if tg.ndim != 3 or tg.shape[1:] != (len(self.points), 3):
            raise SolveError(f"targets must be (T, {len(self.points)}, 3), got {tg.shape}")
        self.reset(q_start)
        out = np.empty((tg.shape[0], self.num_joints))
        fallbacks = 0
        t0 = time.perf_counter()
        for t in range(tg.shape[0]):
            out[t], ok = self.solve(tg[t], dt_s)
            fallbacks += int(not ok)
        return PositionIKResult(out, fallbacks, time.perf_counter() - t0)
