from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.types import JointCommand
from robot_retarget.pipeline.recorder import RecordingBackend
from robot_retarget.robot.config import RobotConfig


def test_reports_the_start_pose_then_the_last_command(op3: RobotConfig) -> None:
    rec = RecordingBackend(op3)
    with pytest.raises(HardwareError, match="connect"):
        rec.send(JointCommand(op3.init_pose))
    with rec:
        np.testing.assert_array_equal(rec.read_state().q, op3.init_pose)
        cmd = JointCommand(op3.safe_pose, 0.5)
        assert rec.send(cmd) is cmd
        np.testing.assert_array_equal(rec.read_state().q, op3.safe_pose)
        assert rec.connected
    assert not rec.connected
    assert rec.sent == [cmd]


def test_custom_start_pose(op3: RobotConfig) -> None:
    rec = RecordingBackend(op3, q0=np.zeros(op3.num_joints))
    rec.connect()
    np.testing.assert_array_equal(rec.read_state().q, 0.0)
