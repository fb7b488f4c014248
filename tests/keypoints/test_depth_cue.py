"""The depth cue: a limb bone's image length tells its angle to the image plane
(robot_retarget.keypoints.reprojection.depth_from_length, DEPTH_SCALE), in ``convert``'s
planes and the stream's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robot_retarget.keypoints.reprojection as reprojection_module
from robot_retarget.evaluation.robot.metrics import segment_angles
from robot_retarget.evaluation.robot.segments import human_body_points
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.camera_fit import ASSUMED_DISTANCE_HEIGHTS
from robot_retarget.keypoints.online_reprojection import OnlineReprojection
from robot_retarget.keypoints.reprojection import DEPTH_BONES, depth_from_length, reproject
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.keypoints.synthetic import CLEAN, render_keypoints
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.skeleton.canonical import Joint

FOCAL = 1000.0


def _bone(phi_deg: float, across: np.ndarray) -> np.ndarray:
    """A unit direction at ``phi_deg`` to the image plane (toward +Z, away from the camera,
    for positive angles), ``across`` (unit, z = 0) its direction in the image."""
    phi = math.radians(phi_deg)
    return np.array([*(math.cos(phi) * across[:2]), math.sin(phi)])


def _rays(image_len: float, across: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two end points' rays of a bone centred on the optical axis, ``image_len`` px long."""
    half = 0.5 * image_len * across[:2]
    return np.array([[*(-half), FOCAL]]), np.array([[*half, FOCAL]])


ACROSS = np.array([0.6, -0.8, 0.0])


def test_a_foreshortened_bone_takes_the_angle_its_length_gives() -> None:
    # The bone is 60 px long in the image where it would be 100 px across the view: 53.1° to
    # the image plane. The model says 20°, on the right side.
    ray_a, ray_b = _rays(60.0, ACROSS)
    model = _bone(20.0, ACROSS)[None]
    nearly_all = depth_from_length(model, ray_a, ray_b, np.array([100.0]), 1e-6)
    np.testing.assert_allclose(nearly_all[0], _bone(math.degrees(math.acos(0.6)), ACROSS))
    # With a share scale of 1 it moves s² / (s² + 1) of the way, s = sin 53.1° = 0.8.
    share = 0.64 / 1.64
    expected = 20.0 + share * (math.degrees(math.acos(0.6)) - 20.0)
    np.testing.assert_allclose(
        depth_from_length(model, ray_a, ray_b, np.array([100.0]), 1.0)[0],
        _bone(expected, ACROSS),
        atol=1e-12,
    )


def test_the_side_toward_or_away_from_the_camera_is_the_models() -> None:
    ray_a, ray_b = _rays(60.0, ACROSS)
    toward = depth_from_length(_bone(-20.0, ACROSS)[None], ray_a, ray_b, np.array([100.0]), 1e-6)
    np.testing.assert_allclose(toward[0], _bone(-math.degrees(math.acos(0.6)), ACROSS))


def test_a_bone_as_long_as_its_full_length_keeps_the_models_angle() -> None:
    # A full-length image says "across the view" only to first order: the cue gets no share.
    for image_len in (100.0, 130.0):
        ray_a, ray_b = _rays(image_len, ACROSS)
        model = _bone(25.0, ACROSS)[None]
        out = depth_from_length(model, ray_a, ray_b, np.array([100.0]), 1.0)
        np.testing.assert_allclose(out, model, atol=1e-12)


def test_missing_end_points_or_no_image_scale_leave_the_bone_as_it_is() -> None:
    ray_a, ray_b = _rays(60.0, ACROSS)
    model = _bone(20.0, ACROSS)[None]
    missing = np.full_like(ray_b, np.nan)
    np.testing.assert_array_equal(
        depth_from_length(model, ray_a, missing, np.array([100.0]), 1.0), model
    )
    for expected in (0.0, -5.0):
        np.testing.assert_array_equal(
            depth_from_length(model, ray_a, ray_b, np.array([expected]), 1.0), model
        )


_finite = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(
    st.tuples(_finite, _finite, _finite),
    st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
    st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
    st.floats(1.0, 400.0),
    st.floats(0.05, 5.0),
)
def test_the_bone_stays_a_unit_vector_in_the_plane_of_itself_and_its_ray(
    d: tuple[float, float, float],
    a: tuple[float, float],
    b: tuple[float, float],
    expected: float,
    scale: float,
) -> None:
    direction = np.array(d)
    if np.linalg.norm(direction) < 1e-3:
        return
    direction = direction / np.linalg.norm(direction)
    ray_a, ray_b = np.array([[*a, FOCAL]]), np.array([[*b, FOCAL]])
    out = depth_from_length(direction[None], ray_a, ray_b, np.array([expected]), scale)[0]
    assert np.linalg.norm(out) == pytest.approx(1.0, abs=1e-9)
    view = (ray_a + ray_b)[0] / np.linalg.norm(ray_a + ray_b)
    # Turned about the axis across both: coplanar with the model's direction and the ray.
    assert abs(np.dot(out, np.cross(direction, view))) < 1e-9


def test_only_the_upper_arms_thighs_and_shins_take_the_cue() -> None:
    from robot_retarget.keypoints.coco17 import LIMB_BONES

    cued = {Joint(b[0]).name for b, on in zip(LIMB_BONES, DEPTH_BONES, strict=True) if on}
    assert cued == {"LeftArm", "RightArm", "LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg"}


def _left_upper_arm_error(truth: HumanMotion, turned: HumanMotion, first: int = 0) -> float:
    """Mean angle (°) of the left upper arm of ``turned`` against the truth, from ``first``."""
    angles = segment_angles(
        human_body_points(truth.positions()), human_body_points(turned.positions())
    )
    return float(np.degrees(angles[first:, 0]).mean())


def _streamed(moved: HumanMotion, seen: KeypointSequence) -> tuple[HumanMotion, int]:
    """``moved`` through the stream's planes, and the first frame they turn."""
    online = OnlineReprojection(moved.skeleton, fps=moved.fps, compiled=False)
    out = np.stack([online.step(q, xy) for q, xy in zip(moved.local_quats, seen.xy, strict=True)])
    return HumanMotion(moved.skeleton, out, moved.root_pos, moved.fps), online.min_frames


def _arm_turned_along_the_view(motion: HumanMotion, degrees: float) -> HumanMotion:
    """``motion`` with its left upper arm turned toward the camera (on +Z) about the axis
    across the bone and the view: its image keeps its direction, only its length changes."""
    glob = motion.global_quats()
    pos = motion.positions()
    axis = np.cross(pos[:, Joint.LeftForeArm] - pos[:, Joint.LeftArm], [0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    turn = quat.from_axis_angle(axis, np.full(len(axis), math.radians(degrees)))
    local = np.array(motion.local_quats)
    parent = motion.skeleton.parents[Joint.LeftArm]
    local[:, Joint.LeftArm] = quat.mul(
        quat.conjugate(glob[:, parent]), quat.mul(turn, glob[:, Joint.LeftArm])
    )
    return HumanMotion(motion.skeleton, local, motion.root_pos, motion.fps)


@pytest.fixture(scope="module")
def foreshortened() -> tuple[HumanMotion, HumanMotion, KeypointSequence]:
    """The performer's left upper arm points 50° toward the camera; the model's only 25°.
    The image planes cannot see that error (the image direction is the same); the arm's
    image length can. (The other way round, a bone across the view that the model turned
    along it, the cue leaves alone: a full-length image says little about the angle.)"""
    truth = _arm_turned_along_the_view(demo_motion(fps=30.0).frames(0, 90), 50.0)
    cam = VirtualCamera(0.0, 0.0, ASSUMED_DISTANCE_HEIGHTS * truth.height_m, FOCAL)
    px, conf, valid = render_keypoints(
        truth.positions(), truth.global_quats(), truth.height_m, cam,
        np.random.default_rng(0), CLEAN,
    )  # fmt: skip
    return truth, _arm_turned_along_the_view(truth, -25.0), KeypointSequence(px, conf, valid, 30.0)


def test_the_stream_turns_a_foreshortened_upper_arm_back(
    foreshortened: tuple[HumanMotion, HumanMotion, KeypointSequence],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    truth, model, seen = foreshortened
    with_cue = _left_upper_arm_error(truth, *_streamed(model, seen))
    monkeypatch.setattr(reprojection_module, "DEPTH_SCALE", 1e6)  # the cue's share all but 0
    without = _left_upper_arm_error(truth, *_streamed(model, seen))
    assert without > 20.0
    assert with_cue < 0.8 * without  # 19.0° against 24.7°


def test_convert_turns_a_foreshortened_upper_arm_back(
    foreshortened: tuple[HumanMotion, HumanMotion, KeypointSequence],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    truth, model, seen = foreshortened
    with_cue = _left_upper_arm_error(truth, reproject(model, seen))
    monkeypatch.setattr(reprojection_module, "DEPTH_SCALE", 1e6)
    without = _left_upper_arm_error(truth, reproject(model, seen))
    assert without > 20.0
    assert with_cue < 0.75 * without  # 16.2° against 24.7°
