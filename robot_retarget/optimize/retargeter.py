"""The Retargeter: per-joint rotation wishes → servo angles within every hard limit.

Two modes share one robot model:

- :meth:`Retargeter.solve` (online): one frame, warm-started from the previous solution and
  multipliers; a JIT-compiled SQP (exact Hessian, daqp) called through ``Function.buffer()``.
- :meth:`Retargeter.solve_clip` (offline): a frame-by-frame pass seeds sliding windows of W
  frames (overlap O) that are solved jointly with velocity/acceleration smoothness (Gauss–Newton
  SQP, osqp); any clip length.

Whatever the solver does, the returned command is projected onto the joint limits and the
velocity box around the previous command and then checked; a failed solve falls back to that
projection and says so (``SolveStatus.FALLBACK``).
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.errors import SolveError
from robot_retarget.optimize.chains import coupled_groups, joints_above
from robot_retarget.optimize.formulation import FOOT_ROWS, TWIST_ROWS, RobotProblem
from robot_retarget.optimize.limb_branches import LimbBranches
from robot_retarget.optimize.limits import project_sequence, velocity_box
from robot_retarget.optimize.objective import ParameterWriter, retarget_objective
from robot_retarget.optimize.online_check import OnlineCheck
from robot_retarget.optimize.result import SolveResult, SolveStatus
from robot_retarget.optimize.solver import (
    STEP_TOL_STATUS,
    STOPPED_SHORT,
    BufferedSolver,
    SolverSpec,
    build_solver,
)
from robot_retarget.optimize.targets import (
    ClipTargets,
    FrameTargets,
    check_array,
    check_dt,
    trunk_bones,
)
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.pose_check import beyond_a_turn
from robot_retarget.robot.retarget_settings import RetargetSettings
from robot_retarget.robot.servo_models import servo_model

_CONSTRAINT_TOL = 1e-6  # twist (rad) / ground (m) violation still called "satisfied"
_NO_GROUND = 1e9  # lower bound for foot heights when the root height is unknown (m)
# A settling solve's time step (s): its velocity box opens to the joint limits and the
# smoothness terms (∝ 1/dt², 1/dt⁴) vanish, so repeated solves converge to the frame's optimum.
_SETTLE_DT_S = 1e3
_SETTLE_SOLVES = 10
_SETTLE_TOL_RAD = 1e-6  # a settle ends when a re-solve moves no joint by more than this
# The pursuit's time step (s): each re-solve moves a joint by at most its speed limit × this
# (0.25-0.3 rad on OP3's and Poppy's servos), and 60 of them cover any joint's range.
_SETTLE_PURSUIT_DT_S = 0.05
_SETTLE_PURSUIT_SOLVES = 60


@dataclass(frozen=True)
class ClipTiming:
    """Where an offline run spent its time (for benchmarks)."""

    seed_time_s: float  # the frame-by-frame pass
    window_times_s: tuple[float, ...]
    window_frames: tuple[int, ...]  # frames committed by each window


def _function_name(text: str) -> str:
    """A valid casadi function name: letters, digits, single underscores."""
    return re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9]", "_", text)).strip("_")


ONLINE_TOL_DU = 1e-4  # the online solver's stationarity tolerance (see Retargeter.__init__)


class Retargeter:
    """Constrained retargeting for one robot; build once, call per frame or per clip.

    ``jit``: compile the online solver (cached on disk in ``cache_dir``); falls back to the
    interpreted solver when ``compiler`` (default gcc/cc) is missing or fails.
    """

    def __init__(
        self,
        config: RobotConfig,
        *,
        settings: RetargetSettings | None = None,
        jit: bool = True,
        cache_dir: str | Path | None = None,
        compiler: str | None = None,
    ) -> None:
        self.config = config
        self.problem = RobotProblem(config)
        self.settings = settings or RetargetSettings.from_mapping(
            config.retarget,
            bone_names=tuple(b.canonical for b in self.problem.bones),
            path=config.source_path,
        )
        self.lower = config.lower
        self.upper = config.upper
        self.max_velocity = config.max_velocity
        self.num_joints = config.num_joints
        self.objective = retarget_objective(self.problem, self.settings)
        self._cache_dir = None if cache_dir is None else Path(cache_dir)
        self._compiler = compiler
        # The online SQP's step tolerance (rad), a share of the finest servo tick on the robot
        # (settings.step_tol_ticks): where steps shrink geometrically, what a solve has left
        # once they are that small moves no joint by a whole tick.
        finest_tick = min(servo_model(j.servo_model).rad_per_tick for j in config.joints)
        self.step_tol_rad = self.settings.step_tol_ticks * finest_tick
        # Stationarity to 1e-4 (not the SQP's default 1e-7): near a straight limb the cost is
        # flat about the limb's own axis and 1e-7 took Poppy 15 iterations at p90 for poses
        # ≤ 1.7e-4 rad apart on the demo, a tenth of a servo tick. From 1e-5 to 1e-4 Poppy's
        # iterations per frame went from 3.07 to 1.95 (p90 7 → 4), commands moved by 2e-4 rad
        # at the median frame and ≤ 4e-3 rad on both robots, and eval-robot scored the same,
        # offline and live, to every digit of its tables.
        self._online = self._build(
            1, "daqp", jit, hessian="exact", tol_du=ONLINE_TOL_DU, min_step=self.step_tol_rad
        )
        self._online_params = self._init_static(self._online, 1)
        # Compiled where the solver is (no compiler named by the caller: interpreted as it).
        self._online_check = OnlineCheck(
            self._online, jit=self._online.jit_used, cache_dir=self._cache_dir
        )
        self._branches = self._build_branches(jit)
        self._offline: BufferedSolver | None = None  # built on first solve_clip
        self._offline_params: ParameterWriter | None = None
        self._cost_fn: ca.Function | None = None
        self.reset()

    # ----------------------------------------------------------------- construction helpers
    def _build(
        self,
        window: int,
        qpsol: str,
        jit: bool,
        hessian: str = "gauss-newton",
        max_iter: int | None = None,
        tol_pr: float = 1e-9,
        tol_du: float = 1e-7,
        min_step: float = 0.0,
    ) -> BufferedSolver:
        nlp = self.problem.build_nlp(window, self.objective)
        spec = SolverSpec(
            name=_function_name(f"retarget_{self.config.name}_w{window}_{qpsol}_{hessian}"),
            qpsol=qpsol,
            hessian=hessian,
            max_iter=self.settings.max_iter if max_iter is None else max_iter,
            tol_pr=tol_pr,
            tol_du=tol_du,
            min_step=min_step,
            jit=jit,
            compiler=self._compiler,
            cache_dir=self._cache_dir,
        )
        solver, jit_used = build_solver(spec, nlp)
        return BufferedSolver(solver, jit_used)

    def _init_static(self, s: BufferedSolver, window: int) -> ParameterWriter:
        """Parameters and bounds that never change between calls; the solver's writer."""
        writer = self.objective.writer(s.p, window)  # writes the terms' constants
        rows = self.problem.constraint_layout
        alpha = np.array([self.settings.twist_limit_rad(b.canonical) for b in self.problem.bones])
        for t in range(window):
            s.lbg[rows.frame(t, TWIST_ROWS)] = -alpha
            s.ubg[rows.frame(t, TWIST_ROWS)] = alpha
            s.lbg[rows.frame(t, FOOT_ROWS)] = -_NO_GROUND
            s.ubg[rows.frame(t, FOOT_ROWS)] = np.inf
        return writer

    def _build_branches(self, jit: bool) -> LimbBranches | None:
        """Multi-starts of every limb (≥ 2 bones sharing joints) on a twin of the online
        solver; None when the robot has no such limb."""
        segments = [((b.start_frame,), (b.end_frame,)) for b in self.problem.bones]
        # A robot's spine (the joints below the bone that spans the trunk) would couple both
        # arms, the head and itself into one group, whose joints zeroed or negated together are
        # no start for any one arm (Poppy: one group of 15 joints). The limbs hang from it.
        bones = self.problem.bones
        spine = set().union(
            *(
                joints_above(self.config, f)
                for k in trunk_bones(self.problem)
                for f in (bones[k].start_frame, bones[k].end_frame)
            )
        )
        bone_groups, joint_groups = coupled_groups(self.config, segments, held=spine)
        limbs = tuple(
            j for g, j in zip(bone_groups, joint_groups, strict=True) if len(g) >= 2 and j.size >= 2
        )
        if not limbs:
            return None
        twin = self._build(1, "daqp", jit, hessian="exact")
        return LimbBranches(twin, self._init_static(twin, 1), limbs, self.lower, self.upper)

    @property
    def limbs(self) -> tuple[IntArray, ...]:
        """Joint indices of each limb the first frame's multi-start solves on its own."""
        return () if self._branches is None else self._branches.limbs

    @property
    def jit_used(self) -> bool:
        """True when the online solver runs compiled code."""
        return self._online.jit_used

    @property
    def bone_names(self) -> tuple[str, ...]:
        """Canonical start joint of each mapped bone, in target order."""
        return tuple(b.canonical for b in self.problem.bones)

    @property
    def end_effector_names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.problem.ee_frames)

    @property
    def q_prev(self) -> FloatArray:
        """The last command (the velocity box of the next online solve is centred on it)."""
        return self._q_prev.copy()

    # ----------------------------------------------------------------- state
    def reset(self, q: npt.ArrayLike | None = None) -> None:
        """Forget the history; the next solve starts from ``q`` (default: the init pose).

        ``q`` may lie outside the joint limits (a robot's measured pose): the following
        commands then move it inside at ≤ v_max.
        """
        q0 = self.config.init_pose if q is None else q
        start = check_array("start pose", q0, (self.num_joints,)).copy()
        _check_single_turn(start, self.config.joint_names, "start pose")
        self._restart(start, start.copy(), np.clip(start, self.lower, self.upper))

    def _restart(self, q_prev: FloatArray, q_prev2: FloatArray, x0: FloatArray) -> None:
        """The history (last two commands) and a cold start of the next solve at ``x0``: no
        multipliers carried over."""
        self._q_prev = q_prev
        self._q_prev2 = q_prev2
        self._online.x0[:] = x0
        self._online.lam_x0[:] = 0.0
        self._online.lam_g0[:] = 0.0

    def warm_up(self, frames: int = 20) -> None:
        """Run a few solves (page in code and caches) before real time; state is restored."""
        saved = (self._q_prev.copy(), self._q_prev2.copy(), self._online.x0.copy())
        dirs = self.bone_directions(self.config.init_pose)
        for _ in range(frames):
            self.solve(FrameTargets(directions=dirs), 1.0 / self.config.control_rate_hz)
        self._restart(*saved)

    # ----------------------------------------------------------------- numeric FK helpers
    def bone_directions(self, q: npt.ArrayLike) -> FloatArray:
        """(B, 3) unit bone directions of the robot at ``q``, root frame."""
        return np.asarray(self.problem.directions_function(np.asarray(q, dtype=float))).T.copy()

    def bone_normals(self, q: npt.ArrayLike) -> FloatArray:
        """(B, 3) unit bone normals of the robot at ``q`` (the orientation term's vectors)."""
        return np.asarray(self.problem.normals_function(np.asarray(q, dtype=float))).T.copy()

    def bone_twists(self, q: npt.ArrayLike) -> FloatArray:
        """(B,) swing–twist twist angles (rad) of each bone's local rotation at ``q``."""
        return np.asarray(self.problem.twists_function(np.asarray(q, dtype=float))).ravel()

    def end_effector_positions(self, q: npt.ArrayLike) -> FloatArray:
        """(E, 3) end-effector positions (m), root frame."""
        return np.asarray(self.problem.ee_function(np.asarray(q, dtype=float))).T.copy()

    # ----------------------------------------------------------------- targets → parameters
    def _write_frame(
        self, s: BufferedSolver, params: ParameterWriter, t: int, targets: FrameTargets
    ) -> None:
        """Validate one frame's targets and write them into parameter block t."""
        params.write_frame(t, targets)
        if self.problem.feet:
            h = targets.root_height_m
            if h is not None and not math.isfinite(h):
                raise SolveError(f"root_height_m must be finite, got {h}; no command was produced")
            s.lbg[self.problem.constraint_layout.frame(t, FOOT_ROWS)] = (
                -_NO_GROUND if h is None else -h
            )

    def _constraint_violation(self, s: BufferedSolver) -> float:
        if s.g.size == 0:
            return 0.0
        g = s.g
        v = max(float((s.lbg - g).max()), float((g - s.ubg).max()), 0.0)
        return v if math.isfinite(v) else math.inf

    def _cost_at(self, s: BufferedSolver, x: FloatArray) -> float:
        """Cost of a (fallback) point of the online problem."""
        if self._cost_fn is None:
            nlp = self.problem.build_nlp(1, self.objective)
            self._cost_fn = ca.Function("cost", [nlp["x"], nlp["p"]], [nlp["f"]])
        return float(self._cost_fn(x, s.p))

    # ----------------------------------------------------------------- online
    def solve(
        self, targets: FrameTargets, dt_s: float, *, q_prev: npt.ArrayLike | None = None
    ) -> SolveResult:
        """One frame. ``q_prev`` overrides the last command (e.g. a measured pose)."""
        dt = check_dt(dt_s)
        s = self._online
        self._write_frame(s, self._online_params, 0, targets)  # validates before solving
        if q_prev is not None:
            self.set_previous_command(q_prev)
        lo, hi = velocity_box(self._q_prev, self.lower, self.upper, self.max_velocity * dt)
        s.lbx[:] = lo
        s.ubx[:] = hi
        s.x0[:] = self.online_start()
        np.minimum(np.maximum(s.x0, lo, out=s.x0), hi, out=s.x0)  # np.clip's wrapper is slower
        self._online_params.write_history(self._q_prev, self._q_prev2, dt)
        return self._solve_online()

    def solve_written(self) -> SolveResult:
        """One frame whose parameters, box (``lbx``/``ubx``) and start point a caller has
        already written into :attr:`online_solver`'s arrays (the live path's compiled frame
        program, :mod:`.live_frame`); solved, projected and checked as :meth:`solve` does."""
        return self._solve_online()

    def online_start(self) -> FloatArray:
        """Where the next online solve starts, before it is clipped to the frame's box: the
        last solution moved on by ``warm_start_step`` × the last step (a new array)."""
        step = self.settings.warm_start_step
        x0 = self._online.x0
        return x0 + step * (self._q_prev - self._q_prev2) if step else x0.copy()

    def set_previous_command(self, q_prev: npt.ArrayLike) -> None:
        """Centre the next online solve's velocity box on ``q_prev`` (e.g. a measured pose)."""
        q = check_array("q_prev", q_prev, (self.num_joints,))
        _check_single_turn(q, self.config.joint_names, "q_prev")
        self._q_prev = q.copy()

    def history(self) -> tuple[FloatArray, FloatArray]:
        """(last command, the one before): the online problem's smoothness history. Read
        only: the arrays are the Retargeter's own."""
        return self._q_prev, self._q_prev2

    @property
    def online_solver(self) -> BufferedSolver:
        """The online solver's bound arrays (p, lbx, ubx, lbg, x0, …)."""
        return self._online

    def write_online_targets(self, targets: FrameTargets) -> None:
        """Validate one frame's targets and write them into the online solver's parameters
        (what :meth:`solve` does first)."""
        self._write_frame(self._online, self._online_params, 0, targets)

    def _solve_online(self) -> SolveResult:
        """Solve the written online problem (its box in the solver's ``lbx``/``ubx``); the
        result projected onto that box, checked and committed as the new history."""
        s = self._online
        lo, hi = s.lbx, s.ubx
        t0 = time.perf_counter()
        converged = s.call()
        elapsed = time.perf_counter() - t0
        finite, violation = self._online_check()
        if not finite:
            violation = math.inf
        if violation <= _CONSTRAINT_TOL:
            status = SolveStatus.OPTIMAL if converged else SolveStatus.MAX_ITER
            q = self._online_check.q.copy()
            cost = float(s.f[0])
            s.lam_x0[:] = s.lam_x
            s.lam_g0[:] = s.lam_g
        else:
            status = SolveStatus.FALLBACK
            # Best feasible point: the iterate if it is a number, else the previous command,
            # projected onto the merged box.
            x = s.x if bool(np.isfinite(s.x).all()) else self._q_prev
            q = np.minimum(np.maximum(x, lo), hi)
            cost = self._cost_at(s, q)
            s.lam_x0[:] = 0.0
            s.lam_g0[:] = 0.0
        self._final_check(q, lo, hi)
        # The count and status text only for a frame that did not end optimal (reading them
        # costs up to a fifth of OP3's solve): a converged live frame reports no count.
        iters: int | None = None
        status_text = ""
        if status is not SolveStatus.OPTIMAL:
            iters, status_text = s.last_status()
            if status is SolveStatus.MAX_ITER and status_text not in STOPPED_SHORT:
                # The solve failed (e.g. a NaN derivative from a robot config whose bone points
                # against its rest direction): its iterate, feasible or not, is no solution.
                status = SolveStatus.FALLBACK
                q = np.minimum(np.maximum(self._q_prev, lo), hi)
                cost = self._cost_at(s, q)
                s.lam_x0[:] = 0.0
                s.lam_g0[:] = 0.0
                self._final_check(q, lo, hi)
            # casadi reports the same status at its floor (solver.MIN_STEP_FLOOR): only a
            # chosen tolerance makes a stop "converged".
            if (
                status is SolveStatus.MAX_ITER
                and status_text == STEP_TOL_STATUS
                and self.step_tol_rad > 0.0
            ):
                status = SolveStatus.STEP_TOL
        self._q_prev2 = self._q_prev
        self._q_prev = q
        s.x0[:] = q
        return SolveResult(
            status=status,
            q=q,
            cost=cost,
            iterations=iters,
            solve_time_s=elapsed,
            max_violation=violation,
            used_fallback=status is SolveStatus.FALLBACK,
            message=status_text,
        )

    def settle(
        self, targets: FrameTargets, branches: tuple[int | None, ...] | None = None
    ) -> SolveResult:
        """One frame solved to its optimum with no velocity limit: the start of a sequence.

        The result becomes the history (as if the robot had rested there), so the next
        :meth:`solve` goes on from it at the velocity limits. Nothing here bounds the jump from
        the previous command: the caller either starts a file there or pursues the result at a
        limited speed (the control loop's ramp). Joint limits and twist bounds still hold.

        The frame has several local optima, so it is solved from the current pose three ways
        and the lowest cost wins: re-solved with no velocity limit, each solve starting where
        the last ended (the SQP's own steps, which can jump far); pursued in steps bounded by
        the servos' speeds over ``_SETTLE_PURSUIT_DT_S`` (a trust region: it cannot jump
        through a twisted pose); and re-solved with each solve starting where the last step's
        extrapolation leads, as a sequence's solves start. That last one alone once threw
        Poppy's first frames of CMU 02_08 and 02_10 into twisted poses that failed their
        constraints (a candidate that fell back loses to one that did not), but it finds
        better optima than both others for Poppy's first frames of 4 of the 70 CMU clips
        (the performer's own directions as targets; cost 0.118 → 0.055 on 02_01; on OP3 for
        none), and of 02_02 through the shipped network (0.074 → 0.049). After each, every
        limb is solved from two more starts (its joints at zero and negated) and takes the
        best optimum: a sequence keeps the branch it starts in (:mod:`.limb_branches`). The
        result's status, iteration count and solve time are those of the winning start's last
        solve; its cost, that of the pose returned.
        """
        start = self._q_prev.copy()
        x0 = self._online.x0.copy()
        candidates = []
        for dt, max_solves, tol, warm in (
            (_SETTLE_DT_S, _SETTLE_SOLVES, _SETTLE_TOL_RAD, False),
            (
                _SETTLE_PURSUIT_DT_S,
                _SETTLE_PURSUIT_SOLVES,
                max(self.step_tol_rad, _SETTLE_TOL_RAD),
                False,
            ),
            (_SETTLE_DT_S, _SETTLE_SOLVES, _SETTLE_TOL_RAD, True),
        ):
            self._restart(start.copy(), start.copy(), x0)
            candidates.append(self._settle_from(targets, dt, max_solves, tol, warm, branches))
        # A point that broke its constraints (fallback) only wins if every candidate did.
        result = min(candidates, key=lambda r: (r.used_fallback, r.cost))
        self._restart(result.q.copy(), result.q.copy(), result.q)
        return result

    def _settle_from(
        self,
        targets: FrameTargets,
        dt_s: float,
        max_solves: int,
        tol_rad: float,
        warm_start: bool,
        branches: tuple[int | None, ...] | None = None,
    ) -> SolveResult:
        """Re-solve one frame from the last command at time step ``dt_s`` until no joint moves
        by more than ``tol_rad`` (at most ``max_solves``), then the limbs' multi-start.
        ``warm_start``: each solve starts where the last step's extrapolation leads, as a
        sequence's solves do; else where the last ended."""
        for k in range(max_solves):
            before = self._q_prev
            if not warm_start:
                self._q_prev2 = before
            result = self.solve(targets, dt_s)
            if k + 1 == max_solves or float(np.max(np.abs(result.q - before))) <= tol_rad:
                break
        if self._branches is not None:
            # Every limb from its best start: a sequence keeps the branch it starts in.
            q, cost = self._branches.best(self._online, result.q, branches)
            result = dataclasses.replace(result, q=q, cost=cost)
        return result

    @staticmethod
    def _final_check(q: FloatArray, lo: FloatArray, hi: FloatArray) -> None:
        # Invariant of the projection above; checked because a servo is on the other side.
        # One reduction for lo ≤ q ≤ hi and finiteness: any NaN or infinity in q (or an
        # infinite bound it meets) makes the largest excess NaN or positive.
        if not float(np.maximum(lo - q, q - hi).max()) <= 0.0:
            raise SolveError(
                "internal error: projected command left its box; no command was produced"
            )

    # ----------------------------------------------------------------- offline
    def solve_clip(
        self,
        targets: ClipTargets,
        dt_s: float,
        *,
        q_start: npt.ArrayLike | None = None,
    ) -> tuple[SolveResult, ClipTiming]:
        """A whole clip; result ``q`` is (T, J), ``cost`` the sum of the window objectives.

        First a frame-by-frame pass (the online solver) gives a feasible trajectory; then
        windows of ``settings.window`` frames, overlapping by ``settings.overlap``, are solved
        jointly from it (smoothness looks ahead as well as back) with a fixed budget of
        ``settings.offline_max_iter`` SQP iterations, so ``MAX_ITER`` is the usual status: each
        iteration lowers the window's cost from the feasible seed. A window whose result
        violates a constraint keeps the frame-by-frame solution. ``q_start``: the pose before
        the first frame (default: the init pose). The online state (``q_prev``) is untouched.
        """
        dt = check_dt(dt_s)
        total = len(targets)
        if total == 0:
            raise SolveError("the clip has no frames; nothing to retarget")
        j = self.num_joints
        w = self.settings.window
        commit_len = w - self.settings.overlap
        q0 = self.config.init_pose if q_start is None else q_start
        prev = check_array("q_start", q0, (j,)).copy()
        for t in range(total):  # validate everything before solving anything
            self._write_frame(self._online, self._online_params, 0, targets.frame(t))
        s, params = self._offline_solver()
        step = self.max_velocity * dt
        velocity_rows = slice(self.problem.constraint_layout.size(w), None)
        s.lbg[velocity_rows] = np.tile(-step, w - 1)
        s.ubg[velocity_rows] = np.tile(step, w - 1)
        t_seed = time.perf_counter()
        seed, seed_status = self._online_pass(targets, dt, prev)
        seed_time = time.perf_counter() - t_seed
        out = np.empty((total, j))
        status: list[SolveStatus] = [SolveStatus.OPTIMAL] * total
        cost = 0.0
        iterations = 0
        worst = 0.0
        kept = 0
        times: list[float] = []
        committed: list[int] = []
        saved_prev, saved_prev2 = self._q_prev, self._q_prev2
        self._q_prev, self._q_prev2 = prev, prev.copy()
        try:
            start = 0
            while start < total:
                n_real = min(w, total - start)
                for t in range(w):  # pad a short last window by repeating its last frame
                    self._write_frame(s, params, t, targets.frame(start + min(t, n_real - 1)))
                params.write_history(self._q_prev, self._q_prev2, dt)
                for t in range(w):
                    lo, hi = velocity_box(self._q_prev, self.lower, self.upper, step * (t + 1))
                    s.lbx[t * j : (t + 1) * j] = lo
                    s.ubx[t * j : (t + 1) * j] = hi
                idx = np.minimum(np.arange(start, start + w), total - 1)
                np.clip(seed[idx].ravel(), s.lbx, s.ubx, out=s.x0)
                s.lam_x0[:] = 0.0
                s.lam_g0[:] = 0.0
                t0 = time.perf_counter()
                converged = s.call()
                times.append(time.perf_counter() - t0)
                iters, _ = s.last_status()
                n_commit = n_real if start + w >= total else min(commit_len, n_real)
                x = s.x.reshape(w, j)
                violation = self._constraint_violation(s) if np.all(np.isfinite(x)) else math.inf
                if violation <= _CONSTRAINT_TOL:
                    cand = x[:n_commit]
                    status[start : start + n_commit] = [
                        SolveStatus.OPTIMAL if converged else SolveStatus.MAX_ITER
                    ] * n_commit
                    cost += float(s.f[0])
                    worst = max(worst, violation)
                else:  # keep the frame-by-frame solution (itself projected when it failed)
                    kept += 1
                    cand = seed[start : start + n_commit]
                    status[start : start + n_commit] = seed_status[start : start + n_commit]
                q = project_sequence(cand, self._q_prev, self.lower, self.upper, step)
                out[start : start + n_commit] = q
                iterations += iters
                committed.append(n_commit)
                self._q_prev2 = q[-2] if n_commit >= 2 else self._q_prev
                self._q_prev = q[-1].copy()
                start += n_commit
        finally:
            self._q_prev, self._q_prev2 = saved_prev, saved_prev2
        self._check_sequence(out, prev, step)
        fallbacks = status.count(SolveStatus.FALLBACK)
        if fallbacks:
            overall = SolveStatus.FALLBACK
        elif SolveStatus.MAX_ITER in status:
            overall = SolveStatus.MAX_ITER
        else:
            overall = SolveStatus.OPTIMAL
        notes = []
        if kept:
            notes.append(f"{kept} of {len(committed)} windows kept the frame-by-frame solution")
        if fallbacks:
            notes.append(f"{fallbacks} frames fell back to the projected previous command")
        result = SolveResult(
            status=overall,
            q=out,
            cost=cost,
            iterations=iterations,
            solve_time_s=seed_time + float(sum(times)),
            max_violation=worst,
            used_fallback=fallbacks > 0,
            message="; ".join(notes),
        )
        return result, ClipTiming(seed_time, tuple(times), tuple(committed))

    def _offline_solver(self) -> tuple[BufferedSolver, ParameterWriter]:
        if self._offline is None or self._offline_params is None:
            st = self.settings
            self._offline = self._build(
                st.window,
                "osqp",
                jit=False,
                hessian="gauss-newton",
                max_iter=st.offline_max_iter,
                tol_pr=1e-7,
                tol_du=1e-4,
            )
            self._offline_params = self._init_static(self._offline, st.window)
        return self._offline, self._offline_params

    def _online_pass(
        self, targets: ClipTargets, dt: float, start: FloatArray
    ) -> tuple[FloatArray, list[SolveStatus]]:
        """Frame-by-frame online solves (the windows' initial guess); online state kept."""
        s = self._online
        saved = (self._q_prev, self._q_prev2, s.x0.copy(), s.lam_x0.copy(), s.lam_g0.copy())
        out = np.empty((len(targets), self.num_joints))
        status: list[SolveStatus] = []
        try:
            self.reset(start)
            for t in range(len(targets)):
                r = self.solve(targets.frame(t), dt)
                out[t] = r.q
                status.append(r.status)
        finally:
            self._q_prev, self._q_prev2 = saved[0], saved[1]
            s.x0[:], s.lam_x0[:], s.lam_g0[:] = saved[2], saved[3], saved[4]
        return out, status

    def _check_sequence(self, q: FloatArray, q_start: FloatArray, step: FloatArray) -> None:
        prev = q_start
        for t in range(q.shape[0]):
            lo, hi = velocity_box(prev, self.lower, self.upper, step)
            self._final_check(q[t], lo, hi)
            prev = q[t]


def _check_single_turn(q: FloatArray, names: tuple[str, ...], what: str) -> None:
    """A pose no single-turn servo can be in (beyond ±2π rad) is in other units."""
    far = beyond_a_turn(q)
    if far.any():
        i = int(np.argmax(far))
        raise SolveError(
            f"{what}: {names[i]} is {q[i]:g} rad, more than a turn; joint angles are radians "
            "(degrees? pass np.radians of them); no command was produced"
        )
