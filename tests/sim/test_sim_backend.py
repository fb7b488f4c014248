"""SimBackend: the kinematic simulator as a JointBackend, no serial port."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend


def test_offline_tracking_with_velocity_limit(op3: RobotConfig) -> None:
    with SimBackend(op3, realtime=False) as sim:
        target = np.clip(op3.init_pose + 1.0, op3.lower, op3.upper)
        sim.send(JointCommand(target, 0.0))
        sim.send(JointCommand(target, 0.1))
        state = sim.read_state()
        moved = np.abs(state.q - op3.init_pose)
        assert np.all(moved <= op3.max_velocity * 0.1 + 1e-9)
        sim.send(JointCommand(target, 2.0))
        np.testing.assert_allclose(sim.read_state().q, target, atol=1e-6)
        assert state.t_s == pytest.approx(0.1)


def test_realtime_uses_the_clock(op3: RobotConfig) -> None:
    now = [0.0]
    sim = SimBackend(op3, clock=lambda: now[0])
    sim.connect()
    target = np.clip(op3.init_pose + 0.2, op3.lower, op3.upper)
    sim.send(JointCommand(target))
    now[0] = 1.0
    np.testing.assert_allclose(sim.read_state().q, target, atol=1e-6)


def test_refuses_nan_and_use_before_connect(op3: RobotConfig) -> None:
    sim = SimBackend(op3, realtime=False)
    with pytest.raises(HardwareError, match="connect"):
        sim.read_state()
    sim.connect()
    with pytest.raises(HardwareError, match="finite"):
        sim.send(JointCommand(np.full(op3.num_joints, np.nan)))
    assert sim.sent == []
    sim.disconnect()
    assert not sim.connected
