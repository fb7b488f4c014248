"""Robot-side metrics: exact reproduction scores 0°, mirrored / late motion scores badly,
root yaw is invisible; violations, speed and jerk are counted as documented."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from robot_retarget.evaluation.robot.metrics import (
    end_effector_errors,
    segment_angles,
    trajectory_stats,
)
from robot_retarget.evaluation.robot.segments import BodyPoints, RobotBodyModel, human_body_points
from robot_retarget.robot.config import RobotConfig
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, MIRROR_PAIRS

FloatArray = np.ndarray


def _mirror(pos: FloatArray) -> FloatArray:
    """Left/right mirror of canonical positions: reflect X (left) and swap the sides' labels."""
    out = pos * np.array([-1.0, 1.0, 1.0])
    swapped = out.copy()
    for left, right in MIRROR_PAIRS:
        i, j = CANONICAL_JOINTS.index(left), CANONICAL_JOINTS.index(right)
        swapped[:, i], swapped[:, j] = out[:, j], out[:, i]
    return swapped


def test_exact_reproduction_scores_zero(
    op3_body: RobotBodyModel, poses: FloatArray, human_for: Callable[..., FloatArray]
) -> None:
    robot = op3_body.body_points(poses)
    human = human_body_points(human_for(poses, 0.8))
    assert np.degrees(segment_angles(human, robot)).max() < 1e-6


def test_mirrored_motion_scores_badly(
    op3_body: RobotBodyModel, poses: FloatArray, human_for: Callable[..., FloatArray]
) -> None:
    robot = op3_body.body_points(poses)
    human = human_body_points(_mirror(human_for(poses)))
    assert np.degrees(segment_angles(human, robot)).mean() > 15.0


def test_time_shifted_motion_scores_badly(
    op3_body: RobotBodyModel, poses: FloatArray, human_for: Callable[..., FloatArray]
) -> None:
    shift = 40  # 0.32 s at 125 Hz
    robot = op3_body.body_points(poses[shift:])
    human = human_body_points(human_for(poses[:-shift]))
    exact = human_body_points(human_for(poses[shift:]))
    assert np.degrees(segment_angles(exact, robot)).mean() < 1e-6
    assert np.degrees(segment_angles(human, robot)).mean() > 10.0


@settings(max_examples=10)
@given(yaw=st.floats(-np.pi, np.pi))
def test_robot_root_yaw_does_not_change_the_score(
    op3_body: RobotBodyModel, poses: FloatArray, human_for: Callable[..., FloatArray], yaw: float
) -> None:
    q = poses[::20]
    human = human_body_points(_mirror(human_for(q)))  # a non-zero score to compare
    base = segment_angles(human, op3_body.body_points(q))
    rot = Rotation.from_euler("z", yaw).as_matrix()
    yawed = op3_body.body_points(q, root_rotation=rot)
    np.testing.assert_allclose(segment_angles(human, yawed), base, atol=1e-9)


@settings(max_examples=30)
@given(seed=st.integers(0, 10_000))
def test_segment_angles_match_arccos(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(2, 4, 9, 3))
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b /= np.linalg.norm(b, axis=-1, keepdims=True)
    zeros = np.zeros((4, 4, 3))
    got = segment_angles(BodyPoints(a, zeros), BodyPoints(b, zeros))
    ref = np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0))
    np.testing.assert_allclose(got, ref, atol=1e-6)


def test_end_effector_errors_are_distances() -> None:
    d = np.zeros((1, 9, 3))
    h = BodyPoints(d, np.zeros((1, 4, 3)))
    r = BodyPoints(d, np.array([[[0.3, 0.4, 0.0], [0, 0, 0], [0, 0, 1.0], [0, 0, 0]]]))
    np.testing.assert_allclose(end_effector_errors(h, r), [[0.5, 0.0, 1.0, 0.0]])


def test_angle_shapes_must_agree() -> None:
    with pytest.raises(ValueError, match="differ in shape"):
        segment_angles(
            BodyPoints(np.zeros((2, 9, 3)), np.zeros((2, 4, 3))),
            BodyPoints(np.zeros((3, 9, 3)), np.zeros((3, 4, 3))),
        )


def test_trajectory_stats_counts(op3: RobotConfig) -> None:
    fps = 125.0
    q = np.tile(op3.init_pose, (10, 1))
    assert trajectory_stats(op3, q, fps).limit_violations == 0
    assert trajectory_stats(op3, q, fps).speed_violations == 0
    bad = q.copy()
    bad[4, 0] = op3.upper[0] + 0.01  # one joint over its limit (and jumping there and back)
    stats = trajectory_stats(op3, bad, fps)
    assert stats.limit_violations == 1
    step = op3.upper[0] + 0.01 - op3.init_pose[0]
    assert step * fps > op3.max_velocity[0]
    assert stats.speed_violations == 2
    assert stats.max_speed_rad_s == pytest.approx(step * fps)
    # Exactly at the servo's speed is allowed.
    ramp = np.tile(op3.init_pose, (5, 1))
    ramp[:, 19] = op3.init_pose[19] + np.arange(1, 6) * op3.max_velocity[19] / fps
    assert trajectory_stats(op3, ramp, fps).speed_violations == 0
    assert trajectory_stats(op3, ramp, fps).max_speed_ratio == pytest.approx(1.0)


def test_jerk_of_a_cubic(op3: RobotConfig) -> None:
    fps = 100.0
    t = np.arange(50) / fps
    q = np.tile(op3.init_pose, (50, 1))
    q[:, 0] += 0.5 * t**3  # d³q/dt³ = 3 rad/s³ on one joint of 20
    stats = trajectory_stats(op3, q, fps)
    assert stats.jerk_rad_s3 == pytest.approx(3.0 / op3.num_joints, rel=1e-6)


def test_trajectory_shape_checked(op3: RobotConfig) -> None:
    with pytest.raises(ValueError, match="q must be"):
        trajectory_stats(op3, np.zeros((5, 3)), 100.0)
