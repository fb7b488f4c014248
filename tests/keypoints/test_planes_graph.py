"""The stream's image planes as compiled graphs: the numpy reference's numbers, frame by frame."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.camera_fit import CameraEstimate
from robot_retarget.keypoints.demo_2d import demo_keypoints
from robot_retarget.keypoints.online_reprojection import OnlineReprojection
from robot_retarget.keypoints.planes_graph import _from_matrix, _into_plane
from robot_retarget.keypoints.reprojection import _into_planes
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.runtime.agnostic2d import load_keypoint_model


def _numbers(camera: CameraEstimate | None) -> list[float]:
    """A camera's numbers (none: an empty list)."""
    if camera is None:
        return []
    return [camera.elevation_rad, camera.focal_px, *camera.principal_px]


def _both(frames: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The compiled and the numpy stream's answers to the same (local, xy) frames."""
    compiled, reference = OnlineReprojection(), OnlineReprojection(compiled=False)
    a = np.stack([compiled.step(q, xy) for q, xy in frames])
    b = np.stack([reference.step(q, xy) for q, xy in frames])
    fitted, expected = _numbers(compiled.camera), _numbers(reference.camera)
    assert len(fitted) == len(expected)  # both fitted one, or neither
    np.testing.assert_allclose(fitted, expected, rtol=1e-12)  # the sums run in another order
    return a, b


def test_the_compiled_stream_is_the_numpy_stream_with_points_missing() -> None:
    """A lifted demo stream whose keypoints drop out (single points, a limb for a while, and
    frames with no body at all): the same rotations to rounding, camera included."""
    seq = demo_keypoints(demo_motion(fps=30.0).frames(0, 120))
    model = load_keypoint_model().online()
    rng = np.random.default_rng(5)
    frames = []
    for t in range(seq.num_frames):
        xy = np.where(seq.valid[t][:, None], seq.xy[t], np.nan)
        xy[rng.random(17) < 0.1] = np.nan
        if 40 <= t < 60:
            xy[[7, 9]] = np.nan  # the left forearm, gone
        if 70 <= t < 74:
            xy[:] = np.nan  # nobody in view
        if t == 80:
            xy[11, 1] = np.nan  # half a point
        frames.append((model.step(seq.xy[t], seq.valid[t]), xy))
    a, b = _both(frames)
    assert np.abs(a - b).max() < 1e-9
    assert quat.angle_between(a, frames[0][0][None]).max() > 0.01  # it did turn bones


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.floats(-3000.0, 3000.0, allow_nan=False), min_size=6 * 34, max_size=6 * 34),
    st.lists(st.booleans(), min_size=6 * 17, max_size=6 * 17),
    st.integers(0, 2**31 - 1),
)
def test_any_frames_give_the_references_numbers(
    coords: list[float], seen: list[bool], seed: int
) -> None:
    """Six frames of any keypoints (coincident, far out, mostly missing) and random poses:
    the compiled step answers what the numpy step does, and unit quaternions."""
    rng = np.random.default_rng(seed)
    xy = np.array(coords).reshape(6, 17, 2)
    xy[~np.array(seen).reshape(6, 17)] = np.nan
    local = quat.normalize(rng.normal(size=(6, 22, 4)) * [4.0, 1.0, 1.0, 1.0])
    a, b = _both(list(zip(local, xy, strict=True)))
    assert np.isfinite(a).all()
    np.testing.assert_allclose(np.linalg.norm(a, axis=-1), 1.0, atol=1e-12)
    assert np.abs(a - b).max() < 1e-8


def test_a_turns_quaternion_is_quaternion_from_matrix_near_a_half_turn_too() -> None:
    """The change's quaternion (from the trace, or Shepperd's pivot past ~160°) is the numpy
    one, w ≥ 0, for turns from none to nearly half a circle about any axis."""
    m = ca.SX.sym("m", 9)
    fn = ca.Function("q", [m], [ca.vertcat(*_from_matrix(tuple(m[i] for i in range(9))))])
    rng = np.random.default_rng(2)
    for angle in (0.0, 0.3, 1.5, 2.7, 2.9, math.pi - 1e-3):
        axis = rng.normal(size=3)
        q = quat.from_axis_angle(axis, angle)
        mat = quat.to_matrix(q)
        got = np.array(fn(mat.reshape(-1))).ravel()
        np.testing.assert_allclose(got, quat.from_matrix(mat), atol=1e-12)
        assert got[0] >= 0.0


def test_a_bone_along_the_view_is_put_on_its_keypoints_side_in_both_steps() -> None:
    """A bone nearly along the view whose small part across it points from the wrist's
    keypoint back toward the elbow's is mirrored onto the keypoints' side; one that would
    have to turn 90° or more stays (numpy reference and compiled graph alike)."""
    d = ca.SX.sym("d", 3)
    a, b = ca.SX.sym("a", 3), ca.SX.sym("b", 3)
    out = _into_plane(tuple(d[i] for i in range(3)), tuple(a[i] for i in range(3)),
                      tuple(b[i] for i in range(3)), ca.SX(1.0), True)  # fmt: skip
    compiled = ca.Function("into_plane", [d, a, b], [ca.vertcat(*out)])
    ray_a, ray_b = np.array([-10.0, 0.0, 1000.0]), np.array([10.0, 0.0, 1000.0])  # a → b: +x
    back = np.array([-0.2, 0.0, 0.98]) / np.linalg.norm([-0.2, 0.0, 0.98])
    reversed_across = np.array([-0.9, 0.0, 0.44]) / np.linalg.norm([-0.9, 0.0, 0.44])
    for direction, expected in (
        (back, back * [-1.0, 1.0, 1.0]),  # mirrored along the view: now from a toward b
        (reversed_across, reversed_across),  # the mirror would turn it by 128°: it stays
    ):
        numpy = _into_planes(direction[None], ray_a[None], ray_b[None])[0]
        np.testing.assert_allclose(numpy, expected, atol=1e-9)
        np.testing.assert_allclose(np.array(compiled(direction, ray_a, ray_b)).ravel(), numpy,
                                   atol=1e-12)  # fmt: skip
