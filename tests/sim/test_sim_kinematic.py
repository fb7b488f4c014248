"""Kinematic servo response: lag, velocity limit, position limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.sim.kinematic import KinematicRobot, ServoDynamics


@settings(max_examples=100)
@given(st.floats(-3, 3), st.floats(-3, 3), st.floats(0.1, 10), st.floats(1e-4, 0.1))
def test_step_respects_velocity_and_limits(q0: float, goal: float, vmax: float, dt: float) -> None:
    s = ServoDynamics(q_rad=q0, max_velocity_rad_s=vmax, lower_rad=-2.0, upper_rad=2.0)
    s.q_rad = min(max(q0, -2.0), 2.0)
    before = s.q_rad
    after = s.step(goal, dt)
    assert abs(after - before) <= vmax * dt + 1e-12
    assert -2.0 <= after <= 2.0
    # never overshoots the (clipped) goal
    g = min(max(goal, -2.0), 2.0)
    assert (before - g) * (after - g) >= -1e-12


def test_first_order_lag_time_constant() -> None:
    s = ServoDynamics(q_rad=0.0, max_velocity_rad_s=100.0, time_constant_s=0.02)
    s.step(1.0, 0.02)
    assert s.q_rad == pytest.approx(1.0 - math.exp(-1.0))


def test_robot_matches_single_servos() -> None:
    robot = KinematicRobot(np.zeros(3), np.array([1.0, 2.0, 3.0]), -np.ones(3), np.ones(3))
    servos = [ServoDynamics(0.0, v, 0.01, -1.0, 1.0) for v in (1.0, 2.0, 3.0)]
    goal = np.array([5.0, -0.3, 0.2])
    robot.command(goal)
    for _ in range(50):
        robot.advance(0.004)
        for s, g in zip(servos, goal, strict=True):
            s.step(g, 0.004)
    np.testing.assert_allclose(robot.q, [s.q_rad for s in servos])
    assert robot.q[0] == pytest.approx(0.2)  # 1 rad/s × 0.2 s, still moving to the limit
    with pytest.raises(ValueError, match="time_constant"):
        KinematicRobot(np.zeros(1), np.ones(1), -np.ones(1), np.ones(1), time_constant_s=0.0)
