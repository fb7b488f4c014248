"""The lifted pose turned into the planes the image puts its bones in."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.evaluation.robot.metrics import segment_angles
from robot_retarget.evaluation.robot.segments import human_body_points
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.camera_fit import ASSUMED_DISTANCE_HEIGHTS, estimate_camera
from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.keypoints.glitch_gate import MAX_PIXELS
from robot_retarget.keypoints.lift import lift_keypoints
from robot_retarget.keypoints.online_reprojection import OnlineReprojection
from robot_retarget.keypoints.reprojection import reproject, smooth_keypoints, smooth_rotations
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.keypoints.synthetic import CLEAN, EstimatorNoise, render_keypoints
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.runtime.agnostic2d import load_keypoint_model
from robot_retarget.skeleton.canonical import Joint

MIN_FRAMES = OnlineReprojection(fps=30.0).min_frames  # at the test clips' frame rate


def _seen(motion: HumanMotion, elevation_deg: float) -> KeypointSequence:
    """``motion`` through a clean camera at azimuth 0 (its heading frame is the world's), at
    the distance reproject assumes."""
    cam = VirtualCamera(
        0.0, math.radians(elevation_deg), ASSUMED_DISTANCE_HEIGHTS * motion.height_m, 1000.0
    )
    px, conf, valid = render_keypoints(
        motion.positions(), motion.global_quats(), motion.height_m, cam,
        np.random.default_rng(0), CLEAN,
    )  # fmt: skip
    return KeypointSequence(px, conf, valid, motion.fps)


def _noisy(motion: HumanMotion, elevation_deg: float) -> KeypointSequence:
    """``motion`` through the same camera as :func:`_seen`, with an estimator's noise."""
    cam = VirtualCamera(
        0.0, math.radians(elevation_deg), ASSUMED_DISTANCE_HEIGHTS * motion.height_m, 1000.0
    )
    px, conf, valid = render_keypoints(
        motion.positions(), motion.global_quats(), motion.height_m, cam,
        np.random.default_rng(3), EstimatorNoise(),
    )  # fmt: skip
    return KeypointSequence(px, conf, valid, motion.fps)


def _segment_error_deg(a: HumanMotion, b: HumanMotion) -> np.ndarray:
    """(T, 9) angles between the scored segments of two motions."""
    return np.degrees(
        segment_angles(human_body_points(a.positions()), human_body_points(b.positions()))
    )


def _bent(motion: HumanMotion, joint: Joint, degrees: float, axis: list[float]) -> HumanMotion:
    """``motion`` with ``joint``'s global rotation turned about a world ``axis``."""
    turn = quat.from_axis_angle(np.array(axis, dtype=np.float64), math.radians(degrees))
    glob = motion.global_quats()
    local = np.array(motion.local_quats)
    parent = motion.skeleton.parents[joint]
    new_global = quat.mul(turn, glob[:, joint])
    local[:, joint] = quat.mul(quat.conjugate(glob[:, parent]), new_global)
    return HumanMotion(motion.skeleton, local, motion.root_pos, motion.fps)


@pytest.fixture(scope="module")
def truth() -> HumanMotion:
    return demo_motion(fps=30.0).frames(0, 90)


def test_camera_elevation_is_found_from_a_true_pose(truth: HumanMotion) -> None:
    for elevation in (0.0, 20.0, 40.0):
        cam = estimate_camera(truth, _seen(truth, elevation).xy)
        assert cam is not None
        assert math.degrees(cam.elevation_rad) == pytest.approx(elevation, abs=1.5)
        assert cam.focal_px == pytest.approx(1000.0, rel=0.1)


def test_a_true_pose_is_left_where_it_is(truth: HumanMotion) -> None:
    # Only the keypoints' smoothing (σ = one frame) moves it: the fast forearms by < 1° on
    # average (< 0.1° unsmoothed).
    out = reproject(truth, _seen(truth, 15.0))
    assert _segment_error_deg(truth, out).mean(axis=0).max() < 1.0


def test_a_bone_turned_across_the_view_is_turned_back(truth: HumanMotion) -> None:
    # The left forearm turned 25° about the camera's axis (+Z from the performer): across the
    # view, so the image sees the whole error.
    bent = _bent(truth, Joint.LeftForeArm, 25.0, [0.0, 0.0, 1.0])
    before = _segment_error_deg(truth, bent)[:, 2]  # the left forearm
    after = _segment_error_deg(truth, reproject(bent, _seen(truth, 10.0)))[:, 2]
    assert before.mean() > 10.0
    assert after.mean() < 0.3 * before.mean()


def test_a_bone_with_a_missing_end_keeps_the_models_direction(truth: HumanMotion) -> None:
    bent = _bent(truth, Joint.LeftForeArm, 25.0, [0.0, 0.0, 1.0])
    seen = _seen(truth, 10.0)
    xy, valid = seen.xy.copy(), seen.valid.copy()
    xy[:, Coco.left_wrist] = np.nan
    valid[:, Coco.left_wrist] = False
    out = reproject(bent, KeypointSequence(xy, seen.confidence, valid, seen.fps))
    # It moves only with the torso's turn (here < 0.01°: the torso was not bent), and by what
    # smoothing the turns over time leaves of the upper arm's turn (its local change and the
    # forearm's, which undoes it, are smoothed each on its own): < 0.05°.
    np.testing.assert_allclose(_segment_error_deg(bent, out)[:, 2], 0.0, atol=0.05)
    assert _segment_error_deg(bent, reproject(bent, seen))[:, 2].mean() > 5.0


def test_rotation_smoothing_averages_rotations_whatever_their_signs() -> None:
    rng = np.random.default_rng(2)
    base = quat.normalize(rng.normal(size=(1, 22, 4)))
    noisy = quat.normalize(base + 0.05 * rng.normal(size=(30, 22, 4)))
    flipped = noisy.copy()
    flipped[::2] *= -1.0  # the same rotations, every other frame written with the other sign
    out = smooth_rotations(flipped, 30.0, 1.0 / 30.0)
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    same = smooth_rotations(noisy, 30.0, 1.0 / 30.0)
    np.testing.assert_allclose(quat.angle_between(out, same), 0, atol=1e-7)
    assert quat.angle_between(out, base).mean() < 0.8 * quat.angle_between(noisy, base).mean()


def test_keypoint_smoothing_keeps_missing_points_missing() -> None:
    rng = np.random.default_rng(1)
    xy = rng.normal(size=(20, 17, 2))
    valid = rng.random((20, 17)) > 0.3
    xy[~valid] = np.nan
    out = smooth_keypoints(xy, valid, 30.0)
    assert np.array_equal(np.isfinite(out).all(axis=-1), valid)
    const = np.where(valid[..., None], 5.0, np.nan)
    np.testing.assert_allclose(smooth_keypoints(const, valid, 30.0)[valid], 5.0)


def test_frame_counts_must_agree(truth: HumanMotion) -> None:
    with pytest.raises(ValueError, match="frames"):
        reproject(truth.frames(0, 10), _seen(truth, 0.0))


def test_stream_lifting_turns_each_frame_with_the_camera_so_far(truth: HumanMotion) -> None:
    """The causal lifting is the stream's: the model's step, then OnlineReprojection frame by
    frame; nothing before MIN_FRAMES is turned, and a frame's answer never depends on later
    frames."""
    seen = _seen(truth, 15.0)
    model = load_keypoint_model(None)
    plain = lift_keypoints(seen, model, causal=True, image_planes=False)
    planes = lift_keypoints(seen, model, causal=True)
    online = OnlineReprojection()
    stepped = np.stack(
        [online.step(q, xy) for q, xy in zip(plain.local_quats, seen.xy, strict=True)]
    )
    np.testing.assert_allclose(planes.local_quats, stepped, atol=1e-12)
    np.testing.assert_array_equal(
        planes.local_quats[: MIN_FRAMES - 1], plain.local_quats[: MIN_FRAMES - 1]
    )
    assert not np.allclose(planes.local_quats[MIN_FRAMES:], plain.local_quats[MIN_FRAMES:])
    short = KeypointSequence(seen.xy[:40], seen.confidence[:40], seen.valid[:40], seen.fps)
    np.testing.assert_allclose(
        lift_keypoints(short, model, causal=True).local_quats, planes.local_quats[:40], atol=1e-12
    )
    online.reset()
    assert online.camera is None


def test_convert_lifting_turns_bones_into_the_image_planes(truth: HumanMotion) -> None:
    seen = _seen(truth, 15.0)
    model = load_keypoint_model(None, whole_clip=True)
    plain = lift_keypoints(seen, model, image_planes=False)
    planes = lift_keypoints(seen, model)
    err_plain = _segment_error_deg(truth, plain).mean()
    err_planes = _segment_error_deg(truth, planes).mean()
    assert err_planes < err_plain


def test_keypoints_that_cannot_tell_the_camera_leave_the_pose_as_it_is(
    truth: HumanMotion,
) -> None:
    seen = _seen(truth, 10.0)
    lone = np.full_like(seen.xy, np.nan)
    valid = np.zeros_like(seen.valid)
    lone[:, Coco.nose], valid[:, Coco.nose] = seen.xy[:, Coco.nose], True  # no bone at all
    assert estimate_camera(truth, lone) is None
    out = reproject(truth, KeypointSequence(lone, seen.confidence, valid, seen.fps))
    assert out is truth


_CLIP_MODEL = load_keypoint_model(whole_clip=True)
_BODY_FRAME = np.zeros(17, dtype=bool)
_BODY_FRAME[5:] = True  # shoulders to ankles: a body the lifting follows


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.floats(-MAX_PIXELS, MAX_PIXELS, allow_nan=False), min_size=34, max_size=34),
    st.lists(st.floats(-1e12, 1e12, allow_nan=False), min_size=68, max_size=68),
    st.lists(st.booleans(), min_size=34, max_size=34),
)
def test_any_keypoints_give_unit_rotations(
    first: list[float], coords: list[float], seen: list[bool]
) -> None:
    """convert's lifting with the image planes: three frames of anything (huge, coincident,
    mostly missing; the first shows a body, within any image, where the glitch gate leaves it)
    give finite unit quaternions."""
    xy = np.array(first + coords).reshape(3, 17, 2)
    valid = np.concatenate([_BODY_FRAME[None], np.array(seen).reshape(2, 17)])
    xy[~valid] = np.nan
    conf = valid.astype(np.float64)
    q = lift_keypoints(KeypointSequence(xy, conf, valid, 30.0), _CLIP_MODEL).local_quats
    assert np.isfinite(q).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)


def test_the_stream_averages_its_turns_over_frames(
    truth: HumanMotion, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The keypoints' frame-to-frame noise is in each frame's turns: averaged over frames, the
    streamed pose moves less from frame to frame than with each frame's own turns."""
    import robot_retarget.keypoints.online_reprojection as online

    seen = _noisy(truth, 10.0)
    model = load_keypoint_model(None)

    def jitter() -> float:
        q = lift_keypoints(seen, model, causal=True).local_quats[MIN_FRAMES:]
        return float(quat.angle_between(q[1:], q[:-1]).mean())

    averaged = jitter()
    monkeypatch.setattr(online, "CHANGE_RATE", 1.0)
    assert averaged < 0.8 * jitter()


def test_the_streams_turns_fade_in(truth: HumanMotion, monkeypatch: pytest.MonkeyPatch) -> None:
    """When the camera is first fitted the turns start from none (a share CHANGE_RATE of the
    way): the robot does not jolt from the model's pose to the turned one."""
    import robot_retarget.keypoints.online_reprojection as online

    seen = _noisy(truth, 10.0)
    model = load_keypoint_model(None)
    plain = lift_keypoints(seen, model, causal=True, image_planes=False).local_quats
    first = MIN_FRAMES - 1  # the first frame with a camera

    def moved() -> float:
        q = lift_keypoints(seen, model, causal=True).local_quats
        return float(quat.angle_between(q[first], plain[first]).max())

    faded = moved()
    monkeypatch.setattr(online, "CHANGE_RATE", 1.0)
    full = moved()
    assert 0.0 < faded < 0.4 * full


def test_the_streams_timing_is_in_seconds_whatever_the_frame_rate() -> None:
    """A 60 fps camera waits as long before turning, and averages the turns over as long, as a
    30 fps one."""
    at30, at60 = OnlineReprojection(fps=30.0), OnlineReprojection(fps=60.0)
    assert (at30.min_frames, at60.min_frames) == (6, 12)
    assert (1.0 - at60.rate) ** 2 == pytest.approx(1.0 - at30.rate)
    with pytest.raises(ValueError, match="fps must be positive"):
        OnlineReprojection(fps=0.0)


def test_a_known_principal_point_is_the_cameras_and_a_new_one_starts_over(
    truth: HumanMotion,
) -> None:
    """Given the image centre, the stream's camera uses it, not the hips' running mean; a
    different one (another camera or resolution) forgets the camera fitted so far."""
    seen = _seen(truth, 15.0)
    model = load_keypoint_model()
    quats = model.run_clip(seen.xy, seen.valid, causal=True, mirror_average=True)
    centre = np.array([640.0, 360.0])
    known, unknown = OnlineReprojection(image_size=(1280.0, 720.0)), OnlineReprojection()
    for q, xy in zip(quats[: MIN_FRAMES + 3], seen.xy, strict=False):
        known.step(q, xy)
        unknown.step(q, xy)
    assert known.camera is not None
    assert unknown.camera is not None
    np.testing.assert_array_equal(known.camera.principal_px, centre)
    assert not np.allclose(unknown.camera.principal_px, centre)
    known.set_image_size((1280.0, 720.0))  # the same: nothing forgotten
    assert known.camera is not None
    known.set_image_size((640.0, 480.0))
    assert known.camera is None
    with pytest.raises(ValueError, match="image size"):
        known.set_image_size((np.nan, 1.0))
