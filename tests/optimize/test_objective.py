"""The objective's named terms: what the writer puts in p is what the builder reads.

The cost of the built NLP at any q, with targets written through the ParameterWriter, must
equal the documented per-term formulas evaluated in numpy.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.optimize import FrameTargets, RetargetSettings
from robot_retarget.optimize.formulation import RobotProblem
from robot_retarget.optimize.objective import Objective, retarget_objective
from robot_retarget.optimize.terms import VelocityTerm
from robot_retarget.robot.config import RobotConfig


@pytest.fixture(scope="module")
def op3_cost(op3: RobotConfig) -> tuple[RobotProblem, Objective, ca.Function, RetargetSettings]:
    prob = RobotProblem(op3)
    st_ = dataclasses.replace(RetargetSettings(), w_orientation=0.3, w_acceleration=1e-7)
    obj = retarget_objective(prob, st_)
    nlp = prob.build_nlp(2, obj)
    return prob, obj, ca.Function("f", [nlp["x"], nlp["p"]], [nlp["f"]]), st_


def _numpy_cost(
    prob: RobotProblem,
    st_: RetargetSettings,
    qs: list[np.ndarray],
    targets: list[FrameTargets],
    q_prev: np.ndarray,
    q_prev2: np.ndarray,
    dt: float,
    init: np.ndarray,
) -> float:
    cost = 0.0
    hist = [q_prev2, q_prev]
    for q, tg in zip(qs, targets, strict=True):
        d = np.asarray(prob.directions_function(q)).T
        n = np.asarray(prob.normals_function(q)).T
        e = np.asarray(prob.ee_function(q)).T
        assert tg.normals is not None
        assert tg.ee_positions is not None
        assert tg.ee_weights is not None
        w_dir = np.array([st_.direction_weight(b.canonical) for b in prob.bones])
        w_ori = np.array([st_.orientation_weight(b.canonical) for b in prob.bones])
        cost += np.sum(w_dir * np.sum((d - tg.directions) ** 2, axis=1))
        cost += np.sum(w_ori * np.sum((n - tg.normals) ** 2, axis=1))
        cost += st_.w_end_effector * np.sum(tg.ee_weights * np.sum((e - tg.ee_positions) ** 2, 1))
        cost += st_.w_velocity * np.sum(((q - hist[-1]) / dt) ** 2)
        cost += st_.w_acceleration * np.sum(((q - 2 * hist[-1] + hist[-2]) / dt**2) ** 2)
        cost += st_.w_init * np.sum((q - init) ** 2)
        hist.append(q)
    return cost


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), dt=st.floats(1e-3, 0.1))
def test_written_parameters_give_the_documented_cost(
    op3_cost: tuple[RobotProblem, Objective, ca.Function, RetargetSettings], seed: int, dt: float
) -> None:
    prob, obj, f, st_ = op3_cost
    cfg = prob.config
    rng = np.random.default_rng(seed)
    nb, ne = len(prob.bones), len(prob.ee_frames)
    p = np.zeros(obj.layout.size(2))
    writer = obj.writer(p, 2)
    targets = []
    for t in range(2):
        dirs = rng.normal(size=(nb, 3))
        tg = FrameTargets(
            directions=dirs / np.linalg.norm(dirs, axis=1, keepdims=True),
            normals=rng.normal(size=(nb, 3)),
            ee_positions=rng.normal(size=(ne, 3)) * 0.2,
            ee_weights=rng.uniform(0.0, 2.0, size=ne),
        )
        writer.write_frame(t, tg)
        targets.append(tg)
    q_prev, q_prev2 = rng.uniform(cfg.lower, cfg.upper), rng.uniform(cfg.lower, cfg.upper)
    writer.write_history(q_prev, q_prev2, dt)
    qs = [rng.uniform(cfg.lower, cfg.upper) for _ in range(2)]
    got = float(f(np.concatenate(qs), p))
    want = _numpy_cost(prob, st_, qs, targets, q_prev, q_prev2, dt, cfg.init_pose)
    assert got == pytest.approx(want, rel=1e-10)


def test_missing_normals_switch_the_orientation_term_off(op3: RobotConfig) -> None:
    prob = RobotProblem(op3)
    obj = retarget_objective(prob, RetargetSettings())
    p = np.zeros(obj.layout.size(1))
    writer = obj.writer(p, 1)
    dirs = np.asarray(prob.directions_function(op3.init_pose)).T
    writer.write_frame(0, FrameTargets(dirs, dirs))
    assert np.all(p[obj.layout.frame(0, "bone_orientation.weight")] > 0.0)
    writer.write_frame(0, FrameTargets(dirs))
    assert np.all(p[obj.layout.frame(0, "bone_orientation.weight")] == 0.0)


def test_terms_need_distinct_names() -> None:
    with pytest.raises(ValueError, match="distinct"):
        Objective([VelocityTerm(1.0), VelocityTerm(2.0)], num_joints=3)
