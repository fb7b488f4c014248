"""Metrics with known answers: zero for identical motions, exact values for known offsets."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.evaluation import metrics
from robot_retarget.evaluation.skeleton_measures import arm_length, leg_length, skeleton_height
from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

Motion = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]


def test_skeleton_measures_of_the_default_adult(skeleton: Skeleton) -> None:
    assert arm_length(skeleton) == pytest.approx(0.28 + 0.25)
    assert leg_length(skeleton) == pytest.approx(0.42 + 0.41)
    # Hips → head joint 0.6 m, hip drop + thigh + shin + ankle height 0.93 m.
    assert skeleton_height(skeleton) == pytest.approx(1.53)
    assert skeleton_height(skeleton.scaled(0.5)) == pytest.approx(0.5 * skeleton_height(skeleton))


def test_identical_motions_score_zero(skeleton: Skeleton, motion: Motion) -> None:
    pos = motion[2]
    assert metrics.position_error(pos, pos, 1.7) == 0.0
    assert metrics.end_effector_error(pos, skeleton, pos, skeleton) == 0.0
    assert metrics.contact_distance_error(pos, skeleton, pos, skeleton) == 0.0
    assert metrics.bone_direction_error_deg(pos, skeleton, pos, skeleton) == pytest.approx(
        0.0, abs=1e-5
    )


@settings(max_examples=20)
@given(d=st.tuples(*[st.floats(-0.5, 0.5)] * 3), height=st.floats(0.3, 2.0))
def test_position_error_of_a_known_offset(d: tuple[float, float, float], height: float) -> None:
    pos = np.random.default_rng(0).normal(size=(5, 22, 3))
    expected = sum(x * x for x in d) / height**2 * 1e3
    assert metrics.position_error(pos + np.array(d), pos, height) == pytest.approx(expected)


def test_scaled_copy_has_no_end_effector_or_contact_error(
    skeleton: Skeleton, motion: Motion
) -> None:
    q, root, pos = motion
    small = skeleton.scaled(0.3)
    small_pos = forward_kinematics(small, q, root * 0.3)[0]
    assert metrics.end_effector_error(pos, skeleton, small_pos, small) == pytest.approx(
        0.0, abs=1e-12
    )
    assert metrics.contact_distance_error(pos, skeleton, small_pos, small) == pytest.approx(
        0.0, abs=1e-12
    )
    assert metrics.bone_direction_error_deg(pos, skeleton, small_pos, small) == pytest.approx(
        0.0, abs=1e-5
    )


def test_mirrored_motion_scores_badly(skeleton: Skeleton, motion: Motion) -> None:
    pos = motion[2]
    mirrored = pos * np.array([-1.0, 1.0, 1.0])
    assert metrics.end_effector_error(pos, skeleton, mirrored, skeleton) > 0.3
    assert metrics.bone_direction_error_deg(pos, skeleton, mirrored, skeleton) > 20.0


def test_known_end_effector_offset(skeleton: Skeleton, motion: Motion) -> None:
    pos = motion[2].copy()
    moved = pos.copy()
    moved[:, 9] += [0.0, 0.0, 0.53]  # left hand one arm length forward
    # One of four effectors is off by exactly one arm length.
    assert metrics.end_effector_error(pos, skeleton, moved, skeleton) == pytest.approx(0.25)


def test_contact_distance_of_hands_moved_apart(skeleton: Skeleton) -> None:
    pos = np.zeros((2, 22, 3))
    pos[:, 13] = [1.0, 0.0, 0.0]  # right hand
    other = pos.copy()
    other[:, 13] = [1.53, 0.0, 0.0]  # half an arm length... plus: 0.53 m = one arm length
    # hand–hand and right hand–hips grow by one arm length; hand–head (head at 0) too.
    d = metrics.contact_distances(other, skeleton) - metrics.contact_distances(pos, skeleton)
    np.testing.assert_allclose(d[:, [0, 2, 4]], 1.0)
    np.testing.assert_allclose(d[:, [1, 3, 5]], 0.0)


@pytest.mark.parametrize("angle_deg", [10.0, 30.0, 75.0])
def test_bone_direction_error_of_a_rotated_flat_pose(
    flat_skeleton: Skeleton, angle_deg: float
) -> None:
    # Every bone lies in the XY plane, so rotating about Z turns each by exactly the angle.
    pos = flat_skeleton.rest_positions()[None]
    rot = quat.from_axis_angle([0.0, 0.0, 1.0], math.radians(angle_deg))
    turned = quat.rotate(rot, pos)
    err = metrics.bone_direction_error_deg(pos, flat_skeleton, turned, flat_skeleton)
    assert err == pytest.approx(angle_deg, abs=1e-6)


def test_zero_length_bones_are_skipped(skeleton: Skeleton) -> None:
    offs = skeleton.offsets.copy()
    offs[2] = 0.0  # DAZ-like missing Spine1
    daz = skeleton.with_offsets(offs)
    pos = daz.rest_positions()[None]
    assert math.isfinite(metrics.bone_direction_error_deg(pos, daz, pos, daz))


def test_twist_share(skeleton: Skeleton) -> None:
    axes = metrics.twist_axes(skeleton)
    ident = quat.identity((3, 22))
    assert metrics.twist_share(ident, skeleton) == 0.0
    big = np.broadcast_to(quat.from_axis_angle(axes, np.full(22, math.radians(120.0))), (3, 22, 4))
    assert metrics.twist_share(big, skeleton) == 1.0
    small = np.broadcast_to(quat.from_axis_angle(axes, np.full(22, math.radians(90.0))), (3, 22, 4))
    assert metrics.twist_share(small, skeleton) == 0.0
    # A swing (about an axis perpendicular to the bone) is not a twist.
    perp = np.cross(axes, [0.3, 0.2, 0.9])
    perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
    swing = np.broadcast_to(
        quat.from_axis_angle(perp, np.full(22, math.radians(150.0))), (3, 22, 4)
    )
    assert metrics.twist_share(swing, skeleton) == 0.0


def test_shape_errors(skeleton: Skeleton) -> None:
    with pytest.raises(ValueError, match="differ in shape"):
        metrics.position_error(np.zeros((3, 22, 3)), np.zeros((4, 22, 3)), 1.0)
    with pytest.raises(ValueError, match="height must be positive"):
        metrics.position_error(np.zeros((3, 22, 3)), np.zeros((3, 22, 3)), 0.0)
    with pytest.raises(ValueError, match="joint positions"):
        metrics.end_effector_error(np.zeros((3, 22)), skeleton, np.zeros((3, 22)), skeleton)
