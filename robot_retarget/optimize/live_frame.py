"""The live path's targets and online solve as two calls: a compiled frame program, then the SQP.

Frame by frame, :class:`robot_retarget.pipeline.step.RetargetStep` turns the network's rotations
into targets (:class:`.targets.FrameTargetBuilder`), the cost terms write them into the online
solver's parameters, the history and the velocity box follow, then the solve: about forty numpy
calls of a few microseconds each around one compiled SQP. Here everything before the solve is
one SX function whose results are bound to the online solver's own arrays (``p``, ``lbx``,
``ubx``; the start point ``x0`` is copied in only for a frame the program takes, since the numpy
path moves on from it), so a frame costs one casadi call, then
:meth:`.retargeter.Retargeter.solve_written`.

The terms' frame writers are affine in the targets (copies, fixed weights, the keypoint term's
fixed chain sums). Their map is read off the numpy writers once per robot, column by column,
and checked on a random frame, so the compiled program cannot drift from them: a writer that is
not affine makes the construction fail with :class:`NotAffineError`. Frames the targets graph
flags as degenerate (its guard) take the numpy path.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction, compile_graph
from robot_retarget.optimize.retargeter import Retargeter
from robot_retarget.optimize.targets import (
    FrameTargetBuilder,
    FrameTargets,
    check_array,
    check_dt,
)
from robot_retarget.optimize.targets_graph import guard_ok
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

_AFFINE_TOL = 1e-9


class NotAffineError(ValueError):
    """A cost term writes its parameters as a non-affine function of the targets (largest
    deviation ``error`` on a random frame): the compiled frame program cannot express it."""

    def __init__(self, error: float) -> None:
        super().__init__(
            f"the cost terms' frame writers are not affine in the targets (off by {error:.3g} "
            "on a random frame); the live path needs affine writers: write the term's "
            "nonlinear part as part of its residual instead"
        )
        self.error = error


class LiveFrameSolver:
    """One robot's online solve fed straight from canonical rotations (the live path).

    :meth:`write` computes the frame's targets and writes the online problem;
    :meth:`Retargeter.solve_written` then solves it. The same commands as
    ``retargeter.solve(builder(quats), dt)`` (tested to 1e-12 on the demo).
    """

    def __init__(self, retargeter: Retargeter, builder: FrameTargetBuilder) -> None:
        self.retargeter = retargeter
        self.builder = builder
        s = retargeter.online_solver
        matrix, offset, lbg = _writer_map(retargeter, builder)
        p_prev, p_prev2, p_inv_dt = retargeter.objective.history_slices()
        fn = _frame_program(
            builder.graph,
            matrix,
            offset,
            (p_prev, p_prev2, p_inv_dt),
            retargeter.lower,
            retargeter.upper,
            retargeter.max_velocity,
        )
        # The start point is the solver's only array the numpy path reads before writing it
        # (Retargeter.online_start): it is copied in only for a frame the program takes.
        self._program = CompiledFunction(fn, res=[s.p, s.lbx, s.ubx, None, None, None])
        self._start = self._program.res[3]
        q_in, self._prev, self._prev2, self._dt, self._x0 = self._program.args
        self._q_in = q_in.reshape(len(CANONICAL_JOINTS), 4)
        self._trunk = self._program.res[4].reshape(3, 3)
        self._guard = self._program.res[5]
        self._lbg = lbg  # constant: the writers' constraint bounds for a frame without height

    def write(
        self, local_quats: npt.ArrayLike, dt_s: float, *, q_prev: npt.ArrayLike | None = None
    ) -> bool:
        """Targets of canonical local rotations (22, 4) written into the online problem for a
        step of ``dt_s``; ``q_prev`` overrides the last command. False: a degenerate frame
        (the caller takes the numpy path, which overwrites everything written here and finds
        the start point as it was)."""
        q = check_array("local rotations", local_quats, (len(CANONICAL_JOINTS), 4))
        dt = check_dt(dt_s)
        r = self.retargeter
        if q_prev is not None:
            r.set_previous_command(q_prev)
        prev, prev2 = r.history()
        s = r.online_solver
        self._q_in[...] = q
        self._prev[:] = prev
        self._prev2[:] = prev2
        self._dt[0] = dt
        self._x0[:] = r.online_start()  # in numpy, as solve(): the same start to the bit
        s.lbg[:] = self._lbg
        self._program()
        if not guard_ok(self._guard):
            return False
        s.x0[:] = self._start
        return True

    def trunk_frame(self) -> FloatArray:
        """The written frame's trunk frame (3, 3) (columns forward, left, up; canonical)."""
        return self._trunk.copy()


def _writer_map(
    retargeter: Retargeter, builder: FrameTargetBuilder
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(A, b, lbg): the online parameters the writers give a frame of targets t (directions,
    normals, end effectors, flattened) are A·t + b, and its constraint bounds lbg."""
    num_bones = len(retargeter.bone_names)
    num_ee = len(retargeter.end_effector_names) if builder.end_effectors else 0
    sizes = (3 * num_bones, 3 * num_bones, 3 * num_ee)
    n = sum(sizes)
    s = retargeter.online_solver
    saved = (s.p.copy(), s.lbg.copy())

    def written(t: FloatArray) -> tuple[FloatArray, FloatArray]:
        d, rest = np.split(t, [sizes[0]])
        nrm, ee = np.split(rest, [sizes[1]])
        retargeter.write_online_targets(
            FrameTargets(
                directions=d.reshape(-1, 3),
                normals=nrm.reshape(-1, 3),
                ee_positions=ee.reshape(-1, 3) if num_ee else None,
            )
        )
        return s.p.copy(), s.lbg.copy()

    try:
        offset, lbg = written(np.zeros(n))
        columns = []
        for k in range(n):
            p, g = written(np.eye(1, n, k)[0])
            if not np.array_equal(g, lbg):
                raise NotAffineError(float(np.max(np.abs(g - lbg))))
            columns.append(p - offset)
        matrix = np.stack(columns, axis=1) if columns else np.zeros((offset.size, 0))
        probe = np.random.default_rng(0).normal(size=n)
        p, g = written(probe)
        error = float(np.max(np.abs(p - (matrix @ probe + offset)), initial=0.0))
        error = max(error, float(np.max(np.abs(g - lbg), initial=0.0)))
        if not error <= _AFFINE_TOL:
            raise NotAffineError(error)
    finally:
        s.p[:], s.lbg[:] = saved
    return matrix, offset, lbg


def _frame_program(
    targets: ca.Function,
    matrix: FloatArray,
    offset: FloatArray,
    history: tuple[slice, slice, slice],
    lower: FloatArray,
    upper: FloatArray,
    max_velocity: FloatArray,
) -> ca.Function:
    """``(q J·4, q_prev, q_prev2, dt, x0) → (p, lbx, ubx, x0 clipped, trunk 9, guard 3)``.

    p = A·t + b with the history written in; the box is
    :func:`robot_retarget.optimize.limits.velocity_box` (an empty interval, a pose outside the
    limits, collapses to the point that moves toward them at full speed)."""
    nj = lower.size
    q = ca.SX.sym("q", targets.nnz_in(0))
    q_prev = ca.SX.sym("q_prev", nj)
    q_prev2 = ca.SX.sym("q_prev2", nj)
    dt = ca.SX.sym("dt")
    x0 = ca.SX.sym("x0", nj)
    dirs, normals, ee, trunk, guard = targets(q)
    t = ca.vertcat(dirs, normals, ee)
    rows: list[ca.SX] = []
    for i in range(offset.size):
        cols = np.flatnonzero(matrix[i])
        rows.append(sum((float(matrix[i, k]) * t[int(k)] for k in cols), ca.SX(float(offset[i]))))
    p = ca.vertcat(*rows)
    p_prev, p_prev2, p_inv_dt = history
    p[p_prev] = q_prev
    p[p_prev2] = q_prev2
    p[p_inv_dt] = 1.0 / dt
    step = ca.DM(max_velocity) * dt
    lo = ca.fmax(ca.DM(lower), q_prev - step)
    hi = ca.fmin(ca.DM(upper), q_prev + step)
    empty = lo > hi
    above = q_prev > ca.DM(upper)
    lo = ca.if_else(empty * (1 - above), hi, lo)
    hi = ca.if_else(empty * above, lo, hi)
    x0c = ca.fmin(ca.fmax(x0, lo), hi)
    return compile_graph("live_frame", [q, q_prev, q_prev2, dt, x0], [p, lo, hi, x0c, trunk, guard])
