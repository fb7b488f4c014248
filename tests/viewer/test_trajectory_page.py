"""The recorded page's robot: at the file's floating base, or standing on the ground."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.viewer.scene import RobotFigure
from robot_retarget.viewer.trajectory_page import TrajectoryPage

pytest.importorskip("viser", reason="the viewer needs the [view] extra (pip install viser)")

OP3 = load_robot_config("op3")


def test_the_robot_stands_at_the_floating_base() -> None:
    n = 5
    q = np.repeat(OP3.init_pose[None, :], n, axis=0)
    pos = np.column_stack([np.linspace(0.0, 1.0, n), np.zeros(n), np.full(n, 0.25)])
    rot = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.linspace(0.0, 1.5, n))
    trajectory = RobotTrajectory(OP3.joint_names, q, 10.0, root_pos=pos, root_quat=rot)
    with TrajectoryPage(OP3, trajectory, port=0, autoplay=False) as page:
        for k in (0, n - 1):
            expected = RobotFigure(OP3).segments(q[k], pos[k], rot[k])
            np.testing.assert_allclose(page.robot_segments(k), expected)
        assert page.show_frame(99) == n - 1


def test_without_a_base_the_robot_stands_on_the_ground() -> None:
    q = np.repeat(OP3.init_pose[None, :], 3, axis=0)
    with TrajectoryPage(OP3, RobotTrajectory(OP3.joint_names, q, 10.0), port=0) as page:
        z = page.robot_segments(0)[..., 2]
    assert z.min() == pytest.approx(0.0, abs=1e-12)
