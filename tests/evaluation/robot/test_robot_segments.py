"""Segment directions and end effectors in the heading-free body frame (human and robot)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from robot_retarget.errors import ConfigError
from robot_retarget.evaluation.robot.metrics import segment_angles
from robot_retarget.evaluation.robot.segments import (
    SEGMENTS,
    RobotBodyModel,
    human_body_points,
    robot_segment_frames,
    trunk_point,
)
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.skeleton.canonical import default_canonical_skeleton

FloatArray = np.ndarray


def test_op3_frames_use_the_bones_and_trunk_points(op3: RobotConfig) -> None:
    f = robot_segment_frames(op3)
    assert f.starts[0] == "l_sho_roll_link"
    assert f.ends[2] == "l_hand"
    assert f.shoulders == ("l_sho_pitch_link", "r_sho_pitch_link")
    assert f.hips == ("l_hip_yaw_link", "r_hip_yaw_link")
    # Upper arm 0.0904 m + forearm 0.15 m (URDF / [RK] hand point).
    assert f.arm_length_m == pytest.approx(0.2404, abs=1e-3)
    assert f.leg_length_m == pytest.approx(0.22015, abs=1e-4)


def test_poppy_has_trunk_points() -> None:
    f = robot_segment_frames(load_robot_config("poppy_humanoid"))
    assert len(set(f.shoulders)) == 2
    assert len(set(f.hips)) == 2


def test_trunk_point_needs_a_shared_chain(op3: RobotConfig) -> None:
    with pytest.raises(ConfigError):
        trunk_point(op3, "l_hand", "l_hand")


def test_zero_pose_is_a_t_pose_like_the_canonical_rest(
    op3: RobotConfig, op3_body: RobotBodyModel
) -> None:
    """Independent reference: OP3's zero pose and the canonical T-pose agree on every limb."""
    robot = op3_body.body_points(np.zeros((1, op3.num_joints)))
    human = human_body_points(default_canonical_skeleton().rest_positions()[None])
    ang = np.degrees(segment_angles(human, robot))[0]
    assert np.all(ang[:8] < 0.1)  # the URDF's elbow sits 0.1 mm below the shoulder roll axis
    assert ang[8] < 1.0  # OP3's trunk axis leans 0.5° (shoulder axes 1 mm behind the hips)
    expected = {"left_upper_arm": (0, 1, 0), "right_forearm": (0, -1, 0), "left_shin": (0, 0, -1)}
    for name, v in expected.items():
        np.testing.assert_allclose(robot.directions[0, SEGMENTS.index(name)], v, atol=2e-3)


@settings(max_examples=15)
@given(yaw=st.floats(-np.pi, np.pi), seed=st.integers(0, 1000))
def test_root_yaw_does_not_change_robot_directions(
    op3: RobotConfig, op3_body: RobotBodyModel, yaw: float, seed: int
) -> None:
    q = np.random.default_rng(seed).uniform(op3.lower, op3.upper, size=(3, op3.num_joints))
    rot = Rotation.from_euler("z", yaw).as_matrix()
    a = op3_body.body_points(q)
    b = op3_body.body_points(q, root_rotation=rot)
    np.testing.assert_allclose(a.directions, b.directions, atol=1e-12)
    np.testing.assert_allclose(a.end_effectors, b.end_effectors, atol=1e-12)


def test_root_pitch_tilts_the_torso(op3: RobotConfig, op3_body: RobotBodyModel) -> None:
    q = np.zeros((1, op3.num_joints))
    tilted = op3_body.body_points(q, root_rotation=Rotation.from_euler("y", 0.3).as_matrix())
    upright = op3_body.body_points(q)
    assert np.degrees(segment_angles(upright, tilted))[0, SEGMENTS.index("torso")] > 15.0


@settings(max_examples=15)
@given(yaw=st.floats(-np.pi, np.pi))
def test_human_frame_is_heading_free(
    op3: RobotConfig, poses: FloatArray, human_for: Callable[..., FloatArray], yaw: float
) -> None:
    a = human_body_points(human_for(poses[:20]))
    b = human_body_points(human_for(poses[:20], yaw))
    np.testing.assert_allclose(a.directions, b.directions, atol=1e-12)
    np.testing.assert_allclose(a.end_effectors, b.end_effectors, atol=1e-12)


def test_human_end_effectors_are_normalised() -> None:
    rest = default_canonical_skeleton().rest_positions()[None]
    ee = human_body_points(rest).end_effectors[0]
    # T-pose: the hand is one arm length sideways of the arm root, which is 0.18 m from the
    # shoulder midpoint; the foot is a leg length below the hip, 0.09 m to the side.
    np.testing.assert_allclose(ee[0], (0.0, (0.18 + 0.53) / 0.53, 0.0), atol=1e-9)
    np.testing.assert_allclose(ee[2], (0.0, 0.09 / 0.83, -1.0), atol=1e-9)


def test_shape_errors(op3_body: RobotBodyModel) -> None:
    with pytest.raises(ValueError, match="positions must be"):
        human_body_points(np.zeros((3, 21, 3)))
    with pytest.raises(ValueError, match="joint angles must be"):
        op3_body.body_points(np.zeros(20))
