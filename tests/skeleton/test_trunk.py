"""The trunk frame: a rotation whose up follows the torso and whose left follows the hips."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.trunk import trunk_frame, trunk_frames, trunk_frames_of_positions

vectors = arrays(np.float64, (3,), elements=st.floats(-10, 10, allow_nan=False))


@given(vectors, vectors)
@example(np.array([0.0, 0.8125, 0.0]), np.array([5.96046448e-08, 2.0, 0.0]))  # hips ≈ along trunk
def test_always_a_rotation(hip_axis: np.ndarray, trunk: np.ndarray) -> None:
    f = trunk_frames(hip_axis, trunk)
    np.testing.assert_allclose(f.T @ f, np.eye(3), atol=1e-9)
    assert np.linalg.det(f) > 0.999


@given(vectors, vectors)
def test_up_follows_the_trunk_and_left_the_hips(hip_axis: np.ndarray, trunk: np.ndarray) -> None:
    f = trunk_frames(hip_axis, trunk)
    n = np.linalg.norm(trunk)
    if n > 1e-6:
        np.testing.assert_allclose(f[:, 2], trunk / n, atol=1e-9)
        side = hip_axis - f[:, 2] * (hip_axis @ f[:, 2])
        if np.linalg.norm(side) > 1e-6:
            np.testing.assert_allclose(f[:, 1], side / np.linalg.norm(side), atol=1e-9)


@given(vectors, vectors)
@example(np.array([0.0, 0.8125, 0.0]), np.array([5.96046448e-08, 2.0, 0.0]))
def test_the_one_frame_version_agrees(hip_axis: np.ndarray, trunk: np.ndarray) -> None:
    np.testing.assert_allclose(
        trunk_frame(hip_axis, trunk), trunk_frames(hip_axis, trunk), atol=1e-9
    )


def test_an_upright_performer_facing_forward_gives_the_canonical_body_axes() -> None:
    f = trunk_frames(np.array([0.3, 0.0, 0.0]), np.array([0.0, 0.5, 0.0]))
    np.testing.assert_allclose(f, [[0, 1, 0], [0, 0, 1], [1, 0, 0]], atol=1e-12)


def test_a_turned_and_leaning_body_turns_its_frame_with_it() -> None:
    """Rotating every joint position rotates the frame by the same rotation."""
    pos = demo_motion(fps=30.0).positions()[:20]
    r = quat.to_matrix(quat.from_axis_angle(np.array([0.3, 1.0, -0.2]), 0.8))
    moved = (pos - pos[:, :1]) @ r.T
    np.testing.assert_allclose(
        trunk_frames_of_positions(moved), r @ trunk_frames_of_positions(pos), atol=1e-9
    )
    hips = 0.5 * (pos[:, Joint.LeftUpLeg] + pos[:, Joint.RightUpLeg])
    shoulders = 0.5 * (pos[:, Joint.LeftArm] + pos[:, Joint.RightArm])
    up = trunk_frames_of_positions(pos)[:, :, 2]
    torso = shoulders - hips
    np.testing.assert_allclose(up, torso / np.linalg.norm(torso, axis=1, keepdims=True))
