"""Bad values handed to the public API's simulator, robot loader and trajectory raise a
RetargetError naming what was wrong (they raised numpy's IndexError, a broadcast error at
connect, a TypeError, or took a NaN pose in silently)."""

from __future__ import annotations

import numpy as np
import pytest

import robot_retarget as rr
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sim.robot_bus import SimulatedRobotBus


@pytest.mark.parametrize(
    ("pose", "says"),
    [
        (np.full(20, np.nan), r"is nan for joint r_sho_pitch: angles must be finite"),
        (np.zeros(4), r"must be one angle per joint of op3, 20 in its joint order, got shape"),
        ("abc", r"must be 20 numbers"),
    ],
)
def test_a_simulator_start_pose_is_checked(pose: object, says: str) -> None:
    config = rr.load_robot("op3")
    with pytest.raises(rr.RetargetError, match="q_rad " + says):
        SimulatedRobotBus(config, pose)  # type: ignore[arg-type]
    with pytest.raises(rr.RetargetError, match="q0 " + says):
        SimBackend(config, q0=pose)  # type: ignore[arg-type]


def test_a_robot_named_by_nothing_is_a_config_error() -> None:
    with pytest.raises(rr.RetargetError, match="named by a config name or a YAML path, got None"):
        rr.load_robot(None)  # type: ignore[arg-type]


def test_a_trajectory_built_from_impossible_values_is_a_retarget_error() -> None:
    with pytest.raises(rr.RetargetError, match="q must have shape"):
        rr.RobotTrajectory(("a", "b"), np.zeros((5, 3)), 125.0)
    with pytest.raises(ValueError, match="fps must be positive"):  # still a ValueError too
        rr.RobotTrajectory(("a",), np.zeros((5, 1)), 0.0)
