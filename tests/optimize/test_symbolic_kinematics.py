"""The CasADi FK must agree with the numpy robot FK (robot_retarget.robot.kinematics)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from robot_retarget.errors import ConfigError
from robot_retarget.optimize.symbolic_kinematics import SymbolicKinematics, rpy_matrix
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics


@pytest.mark.parametrize("robot", ["op3", "poppy", "twist_arm"])
def test_matches_numpy_kinematics(robot: str, request: pytest.FixtureRequest) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    q_sym = ca.SX.sym("q", config.num_joints)
    kin = SymbolicKinematics(config, q_sym)
    names = kin.frame_names()
    pos_fn = kin.positions_function(names)
    rot_fn = kin.rotations_function(names)
    ref = RobotKinematics(config)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(config.lower, config.upper)
        rot_ref, pos_ref = ref.frame_poses(q, names)
        np.testing.assert_allclose(np.asarray(pos_fn(q)).T, pos_ref, atol=1e-12)
        rot = np.asarray(rot_fn(q)).reshape(3, len(names), 3).transpose(1, 0, 2)
        np.testing.assert_allclose(rot, rot_ref, atol=1e-12)


def test_rpy_is_urdf_fixed_axis_order() -> None:
    roll, pitch, yaw = 0.3, -0.7, 1.1
    rx = rpy_matrix((roll, 0.0, 0.0))
    ry = rpy_matrix((0.0, pitch, 0.0))
    rz = rpy_matrix((0.0, 0.0, yaw))
    np.testing.assert_allclose(rpy_matrix((roll, pitch, yaw)), rz @ ry @ rx, atol=1e-15)


def test_unknown_frame_names_the_frames_that_exist(op3: RobotConfig) -> None:
    kin = SymbolicKinematics(op3, ca.SX.sym("q", op3.num_joints))
    with pytest.raises(ConfigError, match="l_el_link") as err:
        kin.pose("no_such_frame")
    assert err.value.key == "bones"


def test_carrier_link_of_child_link_is_the_parent(op3: RobotConfig) -> None:
    kin = SymbolicKinematics(op3, ca.SX.sym("q", op3.num_joints))
    assert kin.carrier_link("l_el_link") == "l_sho_roll_link"
    assert kin.carrier_link("l_hand") == "l_el_link"
    assert kin.carrier_link(op3.root_link) == op3.root_link
