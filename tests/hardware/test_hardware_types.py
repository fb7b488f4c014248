"""JointCommand / JointState: frozen float64 vectors with checked shapes."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.hardware.types import JointCommand, JointState


def test_command_is_a_private_read_only_copy() -> None:
    q = np.array([0.1, 0.2])
    cmd = JointCommand(q, 1.5)
    q[0] = 9.0
    assert cmd.q[0] == 0.1
    assert cmd.q.dtype == np.float64
    assert cmd.t_s == 1.5
    with pytest.raises(ValueError, match="read-only"):
        cmd.q[0] = 1.0
    with pytest.raises(ValueError, match="1-D"):
        JointCommand(np.zeros((2, 2)))


def test_state_shapes_are_checked() -> None:
    n = 3
    s = JointState(np.zeros(n), np.zeros(n), np.zeros(n), np.full(n, 30.0), np.zeros(n, int), 2.0)
    assert s.hardware_error.dtype == np.int64
    assert s.temperature[0] == 30.0
    with pytest.raises(ValueError, match="velocity"):
        JointState(np.zeros(n), np.zeros(2), np.zeros(n), np.zeros(n), np.zeros(n, int))
