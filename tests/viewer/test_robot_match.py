"""The robot of a trajectory file, told by its joint names."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.viewer.robot_match import (
    RobotGuessError,
    TrajectoryMismatchError,
    joint_angles_for,
    robot_for_trajectory,
)


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_joint_names_name_the_robot_in_any_order(robot: str) -> None:
    config = load_robot_config(robot)
    names = tuple(reversed(config.joint_names))
    trajectory = RobotTrajectory(names, np.zeros((2, len(names))), 10.0)
    assert robot_for_trajectory(trajectory).name == config.name


def test_unknown_joints_ask_for_robot() -> None:
    trajectory = RobotTrajectory(("a", "b"), np.zeros((2, 2)), 10.0)
    with pytest.raises(RobotGuessError, match="--robot") as info:
        robot_for_trajectory(trajectory)
    assert info.value.candidates == []
    assert "op3" in info.value.known


def test_angles_are_put_in_the_robot_order() -> None:
    config = load_robot_config("op3")
    names = tuple(reversed(config.joint_names))
    q = np.arange(len(names), dtype=np.float64)[None, :].repeat(2, axis=0)
    ordered = joint_angles_for(config, RobotTrajectory(names, q, 10.0))
    np.testing.assert_array_equal(ordered[0], q[0, ::-1])


def test_a_trajectory_of_another_robot_is_refused_with_the_difference() -> None:
    op3 = load_robot_config("op3")
    poppy = load_robot_config("poppy_humanoid")
    trajectory = RobotTrajectory(poppy.joint_names, np.zeros((2, poppy.num_joints)), 10.0)
    with pytest.raises(TrajectoryMismatchError) as info:
        joint_angles_for(op3, trajectory)
    assert set(info.value.missing) == set(op3.joint_names) - set(poppy.joint_names)
    assert set(info.value.extra) == set(poppy.joint_names) - set(op3.joint_names)
