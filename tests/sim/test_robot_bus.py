from __future__ import annotations

import numpy as np

from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.robot_bus import SimulatedRobotBus


def test_real_sdk_moves_the_simulated_servos(op3: RobotConfig) -> None:
    with SimulatedRobotBus(op3, op3.safe_pose) as sim:
        assert set(sim.ports) == {b.name for b in op3.buses}
        np.testing.assert_allclose(sim.present_q(), op3.safe_pose, atol=0.002)
        backend = sim.backend()
        with backend:
            np.testing.assert_allclose(backend.read_state().q, op3.safe_pose, atol=0.002)
            target = op3.safe_pose + np.clip(0.01, 0, op3.upper - op3.safe_pose)
            backend.send(JointCommand(target, 0.0))
            sim.settle()
            assert all(sim.torque_on())
            np.testing.assert_allclose(sim.goal_q(), target, atol=0.002)
        sim.settle()
        assert not any(sim.torque_on())
        assert sim.packets() > op3.num_joints  # pings, setup writes, goals, reads
