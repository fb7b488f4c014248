"""Scene geometry: the robot placed by its floating base, the performer beside it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.viewer.scene import HUMAN_EDGES, RobotFigure, performer_figure

OP3 = load_robot_config("op3")
FIGURE = RobotFigure(OP3)

unit = st.floats(-1.0, 1.0, allow_nan=False)


@given(
    st.lists(unit, min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.1),
    st.lists(unit, min_size=3, max_size=3),
)
def test_the_base_pose_moves_the_robot_rigidly(q_root: list[float], pos: list[float]) -> None:
    body = FIGURE.points(OP3.init_pose)
    world = FIGURE.points(OP3.init_pose, np.array(pos), np.array(q_root))
    rot = quat.to_matrix(quat.normalize(np.array(q_root)))
    np.testing.assert_allclose(world, body @ rot.T + np.array(pos), atol=1e-12)


def test_points_are_the_kinematics_frames_and_edges_join_parent_to_child() -> None:
    q = np.clip(OP3.init_pose + 0.3, OP3.lower, OP3.upper)
    expected = RobotKinematics(OP3).frame_positions(q)
    np.testing.assert_allclose(FIGURE.points(q), expected)
    segments = FIGURE.segments(q)
    assert segments.shape == (len(FIGURE.edges), 2, 3)
    # Every frame but the root is the end of exactly one segment: the figure is a tree.
    ends = sorted(int(e) for e in FIGURE.edges[:, 1])
    assert ends == list(range(1, len(RobotKinematics(OP3).frame_names)))


def test_batched_frames_match_one_by_one() -> None:
    q = np.stack([OP3.init_pose, np.clip(OP3.init_pose - 0.2, OP3.lower, OP3.upper)])
    pos = np.array([[0.0, 0.0, 0.3], [0.5, -0.1, 0.2]])
    rot = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0]))
    both = FIGURE.segments(q, pos, rot)
    for k in range(2):
        np.testing.assert_allclose(both[k], FIGURE.segments(q[k], pos[k], rot[k]))


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_robot_height_is_a_small_humanoid(robot: str) -> None:
    assert 0.3 < RobotFigure(load_robot_config(robot)).height_m() < 1.0


def test_performer_stands_beside_the_robot_at_its_scale() -> None:
    motion = demo_motion()
    figure = performer_figure(motion, OP3, offset=(0.0, 0.6, 0.0))
    assert figure.points.shape == (motion.num_frames, 22, 3)
    # Pelvis starts above the offset, on the robot's left; feet on the ground (z = 0).
    np.testing.assert_allclose(figure.points[0, Joint.Hips, :2], [0.0, 0.6], atol=1e-9)
    feet = figure.points[:, [Joint.LeftToeBase, Joint.RightToeBase], 2]
    assert np.percentile(feet, 2.0) >= -1e-9
    assert 0.0 < figure.scale < 1.0  # the robot is smaller than the performer
    assert figure.segments(10**6).shape == (len(HUMAN_EDGES), 2, 3)  # clamped to the clip


def test_performer_frame_follows_trajectory_time() -> None:
    figure = performer_figure(demo_motion(fps=30.0), OP3)
    assert figure.frame_at(-0.5) == 0  # a lead-in before the clip shows its first frame
    assert figure.frame_at(1.0) == 30
    assert figure.frame_at(1e6) == figure.num_frames - 1
