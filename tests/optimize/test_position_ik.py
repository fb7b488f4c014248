"""The position-IK baseline: reaches reachable targets, never leaves the limits or the box."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import SolveError
from robot_retarget.optimize.position_ik import PositionIK
from robot_retarget.robot.config import RobotConfig

POINTS = ("l_el_link", "r_el_link", "l_hand", "r_hand",
          "l_knee_center", "r_knee_center", "l_ankle_center", "r_ankle_center")  # fmt: skip
DT_S = 1.0 / 125.0


@pytest.fixture(scope="module")
def ik(op3: RobotConfig) -> PositionIK:
    return PositionIK(op3, POINTS, jit=False)


def test_reaches_reachable_targets(op3: RobotConfig, ik: PositionIK) -> None:
    rng = np.random.default_rng(1)
    goal = np.clip(op3.init_pose + rng.uniform(-0.4, 0.4, op3.num_joints), op3.lower, op3.upper)
    targets = np.tile(ik.positions(goal), (150, 1, 1))  # 1.2 s: enough at the servo speed
    result = ik.solve_clip(targets, DT_S)
    assert result.fallbacks == 0
    assert np.abs(ik.positions(result.q[-1]) - targets[-1]).max() < 1e-4


@settings(max_examples=10)
@given(seed=st.integers(0, 10_000))
def test_stays_inside_limits_and_speed(op3: RobotConfig, ik: PositionIK, seed: int) -> None:
    rng = np.random.default_rng(seed)
    targets = rng.uniform(-0.4, 0.4, size=(12, len(POINTS), 3))  # mostly unreachable
    result = ik.solve_clip(targets, DT_S)
    q = result.q
    assert np.all(q >= op3.lower - 1e-12)
    assert np.all(q <= op3.upper + 1e-12)
    steps = np.abs(np.diff(np.vstack([op3.init_pose[None], q]), axis=0))
    assert np.all(steps <= op3.max_velocity * DT_S * (1 + 1e-12))


def test_bad_inputs(op3: RobotConfig, ik: PositionIK) -> None:
    with pytest.raises(SolveError):
        ik.solve(np.zeros((3, 3)), DT_S)
    with pytest.raises(SolveError):
        ik.solve(np.zeros((len(POINTS), 3)), 0.0)
    with pytest.raises(SolveError):
        ik.solve_clip(np.zeros((4, 2, 3)), DT_S)
    with pytest.raises(SolveError):
        PositionIK(op3, (), jit=False)
    with pytest.raises(SolveError):
        PositionIK(op3, POINTS, weights=[1.0], jit=False)
    with pytest.raises(SolveError):
        PositionIK(op3, POINTS, w_damping=-1.0, jit=False)
