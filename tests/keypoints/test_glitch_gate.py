"""The glitch gate: points no body could have made are marked missing before the lifting
(robot_retarget.keypoints.glitch_gate), and a clean view loses none."""

from __future__ import annotations

import dataclasses

import numpy as np

from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints import lift
from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.keypoints.demo_2d import demo_keypoints
from robot_retarget.keypoints.glitch_gate import REANCHOR_S, KeypointGate, gate_keypoints
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.runtime.agnostic2d import load_keypoint_model

GLITCH_FRAMES = range(30, 361, 15)  # one frame every half second after the first second


def _demo() -> KeypointSequence:
    return demo_keypoints(demo_motion(fps=30.0))  # 12 s, 1280 × 720, estimator-like noise


def _glitched(seq: KeypointSequence, where: tuple[float, float]) -> KeypointSequence:
    xy, valid = seq.xy.copy(), seq.valid.copy()
    for t in GLITCH_FRAMES:
        xy[t, Coco.left_wrist] = where
        valid[t, Coco.left_wrist] = True
    return dataclasses.replace(seq, xy=xy, valid=valid)


def test_a_clean_view_loses_no_point() -> None:
    seq = _demo()
    valid, refused = gate_keypoints(seq.xy, seq.valid, seq.fps)
    assert refused == 0
    np.testing.assert_array_equal(valid, seq.valid)


def test_a_wrist_thrown_across_the_image_is_missing_for_its_frames_only() -> None:
    seq = _demo()
    for where in ((100.0, 700.0), (1e7, -1e7)):
        bad = _glitched(seq, where)
        valid, refused = gate_keypoints(bad.xy, bad.valid, bad.fps)
        assert refused == len(GLITCH_FRAMES)
        expected = seq.valid.copy()
        expected[list(GLITCH_FRAMES), Coco.left_wrist] = False
        np.testing.assert_array_equal(valid, expected)


def test_a_point_that_stays_where_it_jumped_is_taken_after_a_while() -> None:
    """The speed test refuses a jump, then takes the point where it now is once it has stayed
    there REANCHOR_S (an occlusion that ended elsewhere); the nose has no bone test."""
    seq = _demo()
    gate = KeypointGate(seq.fps)
    jump = 90
    refused_at = []
    for t in range(150):
        xy = seq.xy[t].copy()
        if t >= jump:  # far enough that no speed reaches it before REANCHOR_S, then stays
            size = gate.scale.pixels
            assert size is not None
            xy[Coco.nose] += (15.0 * size, 0.0)
        ok = gate.step(xy, seq.valid[t], t / seq.fps)
        if not ok[Coco.nose] and seq.valid[t, Coco.nose]:
            refused_at.append(t)
    assert refused_at[0] == jump
    assert len(refused_at) == round(REANCHOR_S * seq.fps)
    assert refused_at == list(range(jump, jump + len(refused_at)))


def test_the_lifted_pose_barely_notices_a_glitch() -> None:
    """The causal lifting of the demo view with a wrist thrown across the image every half
    second stays within 1° of the clean lifting on average (6° without the gate)."""
    seq = _demo()
    model = load_keypoint_model(None, whole_clip=False)
    clean = lift.lift_keypoints(seq, model, causal=True).local_quats
    gated = lift.lift_keypoints(_glitched(seq, (100.0, 700.0)), model, causal=True).local_quats
    assert float(np.degrees(quat.angle_between(clean, gated)).mean()) < 1.0


def test_a_glitched_shoulder_is_refused_and_its_elbow_kept() -> None:
    """The bone test goes root outward: a shoulder refused for its speed does not also cost
    the elbow it makes look far away."""
    seq = _demo()
    gate = KeypointGate(seq.fps)
    for t in range(45):
        gate.step(seq.xy[t], seq.valid[t], t / seq.fps)
    xy = seq.xy[45].copy()
    xy[Coco.left_shoulder] = (1e200, -1e200)  # and no overflow warning either
    ok = gate.step(xy, seq.valid[45], 45 / seq.fps)
    assert not ok[Coco.left_shoulder]
    assert ok[Coco.left_elbow] == seq.valid[45, Coco.left_elbow]


def test_a_sender_restart_starts_the_gate_over() -> None:
    """A clock that goes back is a new sender (maybe another person): nothing is refused for
    having moved since the old one's frames."""
    seq = _demo()
    gate = KeypointGate(seq.fps)
    for t in range(60):
        gate.step(seq.xy[t + 200], seq.valid[t + 200], t / seq.fps)
    for t in range(30):
        ok = gate.step(seq.xy[t], seq.valid[t], t / seq.fps)
        np.testing.assert_array_equal(ok, seq.valid[t])
    assert gate.refused == 0


def test_a_shoulder_thrown_before_the_speed_test_is_judged_on_the_trunk() -> None:
    """In a stream's first half second only the lengths count: a shoulder thrown sideways
    makes its shoulder line and its side of the torso both too long, so the shoulder is the
    one refused, not the elbow it makes look far away."""
    seq = _demo()
    gate = KeypointGate(seq.fps)
    for t in range(3):
        gate.step(seq.xy[t], seq.valid[t], t / seq.fps)
    assert gate.scale.pixels is not None
    assert not gate.scale.settled
    xy = seq.xy[3].copy()
    xy[Coco.right_shoulder] += (-3.0 * gate.scale.pixels, 0.0)
    ok = gate.step(xy, seq.valid[3], 3 / seq.fps)
    assert not ok[Coco.right_shoulder]
    np.testing.assert_array_equal(
        np.delete(ok, Coco.right_shoulder), np.delete(seq.valid[3], Coco.right_shoulder)
    )


def test_a_shoulder_that_jumps_within_the_speed_allowance_is_the_one_refused() -> None:
    """A shoulder thrown up by 1.2 body sizes in one frame (under the speed test's allowance)
    makes its upper arm too long; the shoulder jumped, the elbow did not, so the shoulder goes."""
    seq = _demo()
    gate = KeypointGate(seq.fps)
    for t in range(45):
        gate.step(seq.xy[t], seq.valid[t], t / seq.fps)
    assert gate.scale.settled
    assert gate.scale.pixels is not None
    xy = seq.xy[45].copy()
    xy[Coco.left_shoulder] += (0.0, -1.2 * gate.scale.pixels)
    ok = gate.step(xy, seq.valid[45], 45 / seq.fps)
    assert not ok[Coco.left_shoulder]
    assert ok[Coco.left_elbow] == seq.valid[45, Coco.left_elbow]


def test_a_coordinate_no_image_has_is_missing_from_the_first_frame() -> None:
    """1e200 px in a stream's very first frame, before the body's size is known: missing, and
    the image's planes fitted on the stream stay finite."""
    from robot_retarget.keypoints.online_reprojection import OnlineReprojection

    seq = _demo()
    gate = KeypointGate(seq.fps)
    planes = OnlineReprojection(fps=seq.fps, image_size=None)
    rest = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (22, 1))
    for t in range(60):
        xy = seq.xy[t].copy()
        if t == 0:
            xy[Coco.left_hip] = (1e200, 1e200)
        ok = gate.step(xy, seq.valid[t], t / seq.fps)
        assert ok[Coco.left_hip] == (t > 0 and seq.valid[t, Coco.left_hip])
        out = planes.step(rest, np.where(ok[:, None], xy, np.nan))
        assert np.isfinite(out).all()
    assert gate.refused == 1
    camera = planes.camera
    assert camera is not None
    assert np.isfinite(camera.principal_px).all()
