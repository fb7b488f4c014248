"""Solver construction: options, cache keys, buffered calls."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robot_retarget.casadi_jit import CACHE_ENV, default_cache_dir, find_compiler
from robot_retarget.optimize.formulation import RobotProblem
from robot_retarget.optimize.objective import retarget_objective
from robot_retarget.optimize.solver import BufferedSolver, SolverSpec, build_solver, cache_key
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.retarget_settings import RetargetSettings


def test_cache_key_depends_on_expressions_and_options(twist_arm: RobotConfig) -> None:
    prob = RobotProblem(twist_arm)
    spec = SolverSpec(name="s", qpsol="daqp", max_iter=20, jit=True)
    assert cache_key(spec, prob.build_nlp(1)) == cache_key(
        spec, RobotProblem(twist_arm).build_nlp(1)
    )
    assert cache_key(spec, prob.build_nlp(1)) != cache_key(spec, prob.build_nlp(2))
    other = SolverSpec(name="s", qpsol="daqp", max_iter=10, jit=True)
    assert cache_key(spec, prob.build_nlp(1)) != cache_key(other, prob.build_nlp(1))


def test_cache_dir_from_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    assert default_cache_dir() == tmp_path
    monkeypatch.delenv(CACHE_ENV)
    assert default_cache_dir().name == "robot_retarget"


def test_find_compiler() -> None:
    assert find_compiler("no-such-cc-for-robot-retarget") is None


def _solver_toward(
    arm: RobotConfig, q: np.ndarray, *, qpsol: str, max_iter: int
) -> tuple[ca.Function, BufferedSolver]:
    """An interpreted one-frame solver whose bone-direction targets are those of pose ``q``,
    within the joint limits, from the zero start."""
    prob = RobotProblem(arm)
    spec = SolverSpec(name="t", qpsol=qpsol, max_iter=max_iter, jit=False, hessian="exact")
    solver, jit_used = build_solver(spec, prob.build_nlp(1))
    assert not jit_used
    buffered = BufferedSolver(solver, jit_used)
    lay = retarget_objective(prob, RetargetSettings()).layout
    buffered.p[lay.frame(0, "bone_direction.target")] = np.asarray(
        prob.directions_function(q)
    ).T.ravel()
    buffered.p[lay.frame(0, "bone_direction.weight")] = 1.0
    buffered.lbx[:] = arm.lower
    buffered.ubx[:] = arm.upper
    buffered.lbg[:] = -np.inf
    buffered.ubg[:] = np.inf
    return solver, buffered


@pytest.mark.parametrize("qpsol", ["daqp", "qrqp", "osqp"])
def test_buffered_solve_matches_plain_call(twist_arm: RobotConfig, qpsol: str) -> None:
    q = np.random.default_rng(0).uniform(twist_arm.lower, twist_arm.upper)
    solver, buffered = _solver_toward(twist_arm, q, qpsol=qpsol, max_iter=20)
    converged = buffered.call()
    iters, status = buffered.last_status()
    assert converged, status
    assert iters >= 1
    assert status == "Solve_Succeeded"
    plain = solver(
        x0=buffered.x0, p=buffered.p, lbx=buffered.lbx, ubx=buffered.ubx,
        lbg=buffered.lbg, ubg=buffered.ubg,
    )  # fmt: skip
    np.testing.assert_allclose(buffered.x, np.asarray(plain["x"]).ravel(), atol=1e-7)


def test_a_solve_stopped_at_max_iter_says_so_and_keeps_its_iterate(
    twist_arm: RobotConfig,
) -> None:
    """A solve that does not converge is how casadi's error_on_fail reaches call(): False, the
    iterate written, and the count and status on demand."""
    q = np.clip(np.full(twist_arm.num_joints, 1.2), twist_arm.lower, twist_arm.upper)
    _, buffered = _solver_toward(twist_arm, q, qpsol="daqp", max_iter=1)
    buffered.x[:] = np.nan  # the iterate must be written over this
    assert not buffered.call()
    assert buffered.last_status() == (1, "Maximum_Iterations_Exceeded")
    assert np.all(np.isfinite(buffered.x))
    assert not np.allclose(buffered.x, 0.0)  # one step moved it from the start (zeros)


def test_unknown_choices_are_rejected(twist_arm: RobotConfig) -> None:
    nlp = RobotProblem(twist_arm).build_nlp(1)
    with pytest.raises(ValueError, match="QP solver"):
        build_solver(SolverSpec(name="t", qpsol="nope", max_iter=5, jit=False), nlp)
    with pytest.raises(ValueError, match="Hessian"):
        build_solver(SolverSpec(name="t", qpsol="daqp", max_iter=5, jit=False, hessian="x"), nlp)


def test_a_ctrl_c_inside_the_solve_is_a_keyboard_interrupt(twist_arm: RobotConfig) -> None:
    """casadi runs Python's SIGINT handler from inside a call and returns its KeyboardInterrupt
    as a RuntimeError (seen in a stream stopped by Ctrl-C mid-solve); the loop's smooth stop
    catches KeyboardInterrupt, so the solver gives it back as one. Other errors stay errors."""
    spec = SolverSpec(name="t", qpsol="daqp", max_iter=20, jit=False, hessian="exact")
    buffered = BufferedSolver(*build_solver(spec, RobotProblem(twist_arm).build_nlp(1)))

    def interrupted() -> None:
        raise RuntimeError(".../casadi/core/function_internal.hpp:1295: KeyboardInterrupt")

    def broken() -> None:
        raise RuntimeError("Error in Function::call for 'solver': something else")

    buffered._trigger = interrupted
    with pytest.raises(KeyboardInterrupt):
        buffered.call()
    buffered._trigger = broken
    with pytest.raises(RuntimeError, match="something else"):
        buffered.call()
