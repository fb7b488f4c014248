"""Live COCO-17 keypoints over UDP: packets in, canonical frames out (through the keypoint
model's causal step), with the 3D UDP source's rules: loopback by default, token, drops counted."""

from __future__ import annotations

import dataclasses
import json
import socket
import time

import numpy as np
import pytest
import torch

from robot_retarget.errors import SourceError
from robot_retarget.nn.models.agnostic2d import Agnostic2D
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime
from robot_retarget.sources import open_source
from robot_retarget.sources.base import SourceFrame
from robot_retarget.sources.keypoints.udp_keypoints import UdpKeypointSource
from robot_retarget.sources.keypoints.wire import decode_keypoints, encode_keypoints
from robot_retarget.sources.wire import WireError


@pytest.fixture(scope="module")
def runtime() -> Agnostic2DRuntime:
    torch.manual_seed(1)
    return Agnostic2DRuntime(
        Agnostic2D(channels=16, static_hidden=8, head_hidden=16).export_weights()
    )


def _person(x0: float, scale: float = 1.0) -> np.ndarray:
    k = np.arange(17)
    return np.stack([x0 + 5.0 * k * scale, 100.0 + 20.0 * k * scale, np.full(17, 0.9)], axis=1)


def _wait(src: UdpKeypointSource, count: int, timeout_s: float = 3.0) -> list[SourceFrame]:
    out: list[SourceFrame] = []
    deadline = time.monotonic() + timeout_s
    while len(out) < count and time.monotonic() < deadline:
        out += src.poll(time.monotonic())
        time.sleep(0.005)
    return out


def test_packets_over_loopback_become_canonical_frames(runtime: Agnostic2DRuntime) -> None:
    src = UdpKeypointSource(runtime, "127.0.0.1", 0, token="tok")
    with src, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for seq in range(1, 4):
            people = [_person(50.0, 0.3), _person(400.0)]  # the larger one is followed
            tx.sendto(encode_keypoints(seq, seq / 30, people, token="tok"), src.address)
        frames = _wait(src, 3)
    assert [f.seq for f in frames] == [1, 2, 3]
    for f in frames:
        assert f.local_quats.shape == (22, 4)
        np.testing.assert_allclose(np.linalg.norm(f.local_quats, axis=-1), 1.0, atol=1e-9)
        assert f.root_pos[1] > 0.5  # held at standing hip height
    assert src.describe().startswith("udp-keypoints://127.0.0.1:")


def test_bad_packets_are_counted_never_raised(runtime: Agnostic2DRuntime) -> None:
    src = UdpKeypointSource(runtime, "127.0.0.1", 0, token="tok")
    good = encode_keypoints(5, 1.0, [_person(0.0)], token="tok")
    assert src.handle_packet(good, 0.0) is not None
    short = json.loads(good)
    short["people"][0]["keypoints"] = short["people"][0]["keypoints"][:16]
    broken = json.loads(good)  # a point with a score and no position: the sender's fault
    broken["people"][0]["keypoints"][3][0] = float("nan")
    cases = {
        "nan": json.dumps(broken).encode(),  # was taken as the point not seen (no_person)
        "duplicate": good,
        "out_of_order": encode_keypoints(4, 0.5, [_person(0.0)], token="tok"),
        "auth": encode_keypoints(6, 1.1, [_person(0.0)], token="nope"),
        "malformed": json.dumps(short).encode(),
        "oversized": b"{" + b" " * 40000 + b"}",
    }
    for reason, data in cases.items():
        before = src.stats.dropped[reason]
        assert src.handle_packet(data, 0.0) is None
        assert src.stats.dropped[reason] == before + 1, reason
    unseen = json.loads(encode_keypoints(7, 1.2, [_person(0.0)], token="tok"))
    unseen["people"][0]["keypoints"][3] = [float("nan"), float("nan"), 0.0]  # not seen: marked
    assert src.handle_packet(json.dumps(unseen).encode(), 0.0) is not None


def test_nobody_in_view_is_a_frame_of_missing_points(runtime: Agnostic2DRuntime) -> None:
    src = UdpKeypointSource(runtime, "127.0.0.1", 0)
    assert src.handle_packet(encode_keypoints(1, 0.0, []), 0.0) is None
    assert src.stats.dropped["no_person"] == 1
    occluded = _person(0.0)
    occluded[5:12, 2] = 0.05  # 7 of the 12 body points below the threshold: 5 seen
    assert src.handle_packet(encode_keypoints(2, 0.05, [occluded]), 0.0) is None
    occluded[5, 2] = 0.9  # 6 seen: enough
    assert src.handle_packet(encode_keypoints(3, 0.1, [occluded]), 0.0) is not None
    assert src.stats.dropped["no_person"] == 2
    low = _person(0.0)
    low[:, 2] = 0.1  # below the confidence threshold
    pkt = decode_keypoints(encode_keypoints(4, 0.2, [low]), 0.3)
    assert not pkt.people[0][2].any()


def test_remote_bind_needs_permission(runtime: Agnostic2DRuntime) -> None:
    with pytest.raises(SourceError, match="not loopback"):
        UdpKeypointSource(runtime, "0.0.0.0", 0)
    with pytest.raises(SourceError, match="not loopback"):
        open_source("udp-keypoints://0.0.0.0:9751")


def test_the_stream_lifts_as_the_causal_clip_lifting_does() -> None:
    """Packet by packet, the source's frames (keypoint model's step, then the image's planes
    with the camera fitted so far) are lift_keypoints(causal=True) of the same keypoints; with
    image_planes=False, the model's step alone. To float32 precision: the live step runs in the
    weights' float32, the clip lifting in float64."""
    from robot_retarget.keypoints.demo_2d import demo_keypoints
    from robot_retarget.keypoints.lift import lift_keypoints
    from robot_retarget.keypoints.sequence import KeypointSequence
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.runtime.agnostic2d import load_keypoint_model

    model = load_keypoint_model()
    seq = demo_keypoints(demo_motion(fps=30.0).frames(0, 40))
    for planes in (True, False):
        src = UdpKeypointSource(model, "127.0.0.1", 0, image_planes=planes)
        frames = []
        for t in range(seq.num_frames):
            person = np.concatenate([np.nan_to_num(seq.xy[t]), seq.confidence[t][:, None]], 1)
            frame = src.handle_packet(encode_keypoints(t + 1, t / 30.0, [person]), 0.0)
            assert frame is not None
            frames.append(frame.local_quats)
        same = KeypointSequence(seq.xy, seq.confidence, seq.valid, seq.fps)
        lifted = lift_keypoints(same, model, causal=True, image_planes=planes)
        np.testing.assert_allclose(np.stack(frames), lifted.local_quats, atol=2e-6)
        # stream prints the camera the planes fitted (or that they were off).
        # stream prints the glitch gate's count and the camera (or that the planes were off).
        gate, line = src.report_lines()
        assert gate.startswith("glitch gate: 0 point(s)")
        assert ("camera estimated at" in line) if planes else ("off" in line)
    fresh = UdpKeypointSource(model, "127.0.0.1", 0)
    assert "no camera fitted" in fresh.report_lines()[1]


def test_a_known_image_size_puts_the_principal_point_at_the_image_centre() -> None:
    """With the image size, from the packets or given to the source, the stream lifts as the
    causal clip lifting of a sequence that knows it; the camera's principal point is the image
    centre, not the hips' running mean, and the report says which it used."""
    from robot_retarget.keypoints.demo_2d import demo_keypoints
    from robot_retarget.keypoints.lift import lift_keypoints
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.runtime.agnostic2d import load_keypoint_model

    model = load_keypoint_model()
    seq = demo_keypoints(demo_motion(fps=30.0).frames(0, 40))
    size = seq.image_size
    assert size is not None
    lifted = lift_keypoints(seq, model, causal=True).local_quats
    by_hips = lift_keypoints(dataclasses.replace(seq, image_size=None), model, causal=True)
    assert np.abs(lifted - by_hips.local_quats).max() > 1e-4  # the principal point matters
    for in_packets in (True, False):
        src = UdpKeypointSource(model, "127.0.0.1", 0, image_size=None if in_packets else size)
        frames = []
        for t in range(seq.num_frames):
            person = np.concatenate([np.nan_to_num(seq.xy[t]), seq.confidence[t][:, None]], 1)
            packet = encode_keypoints(
                t + 1, t / 30.0, [person], image_size=size if in_packets else None
            )
            frame = src.handle_packet(packet, 0.0)
            assert frame is not None
            frames.append(frame.local_quats)
        np.testing.assert_allclose(np.stack(frames), lifted, atol=2e-6)
        _gate, line = src.report_lines()
        assert f"principal point at the image centre ({size[0] / 2:.0f}, {size[1] / 2:.0f})" in line
    hips = UdpKeypointSource(model, "127.0.0.1", 0)
    for t in range(10):
        person = np.concatenate([np.nan_to_num(seq.xy[t]), seq.confidence[t][:, None]], 1)
        hips.handle_packet(encode_keypoints(t + 1, t / 30.0, [person]), 0.0)
    assert "mean hip position (no image size: pass --image-size" in hips.report_lines()[1]


def test_image_sizes_in_packets_are_checked() -> None:
    person = _person(100.0)
    packet = decode_keypoints(encode_keypoints(1, 0.0, [person], image_size=(640, 480)), 0.3)
    assert packet.image_size == (640.0, 480.0)
    assert decode_keypoints(encode_keypoints(1, 0.0, [person]), 0.3).image_size is None
    for bad in ([640], [640, 0], [640, "480"], [True, 480], "640x480", [640, 1e400]):
        obj = json.loads(encode_keypoints(1, 0.0, [person]))
        obj["image_size"] = bad
        with pytest.raises(WireError, match="'image_size' must be"):
            decode_keypoints(json.dumps(obj).encode(), 0.3)


def test_a_glitched_wrist_is_gated_in_the_stream_as_in_the_clip_lifting() -> None:
    """One wrist thrown across the image every half second: the stream's gate marks each
    missing (and says how many), and the stream still lifts as the causal clip lifting."""
    from robot_retarget.keypoints.demo_2d import demo_keypoints
    from robot_retarget.keypoints.lift import lift_keypoints
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.runtime.agnostic2d import load_keypoint_model

    model = load_keypoint_model()
    seq = demo_keypoints(demo_motion(fps=30.0).frames(0, 90))
    xy, valid = seq.xy.copy(), seq.valid.copy()
    glitches = range(30, 90, 15)
    xy[list(glitches), 9] = (100.0, 700.0)
    valid[list(glitches), 9] = True
    seq = dataclasses.replace(seq, xy=xy, valid=valid)
    src = UdpKeypointSource(model, "127.0.0.1", 0, image_size=seq.image_size)
    frames = []
    for t in range(seq.num_frames):
        person = np.concatenate([np.nan_to_num(seq.xy[t]), seq.confidence[t][:, None]], 1)
        person[valid[t], 2] = np.maximum(person[valid[t], 2], 0.9)
        frame = src.handle_packet(encode_keypoints(t + 1, t / 30.0, [person]), 0.0)
        assert frame is not None
        frames.append(frame.local_quats)
    assert src.report_lines()[0].startswith(f"glitch gate: {len(glitches)} point(s)")
    lifted = lift_keypoints(seq, model, causal=True).local_quats
    np.testing.assert_allclose(np.stack(frames), lifted, atol=2e-6)


def test_a_sender_restart_starts_the_stream_over() -> None:
    """After a restart (sequence and clock back to 0) the frames are a fresh source's: the
    old performer's place, the model's context and the camera fitted so far are forgotten,
    so a performer elsewhere in the image is followed from the first packet."""
    from robot_retarget.keypoints.demo_2d import demo_keypoints
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.runtime.agnostic2d import load_keypoint_model

    model = load_keypoint_model()
    seq = demo_keypoints(demo_motion(fps=30.0).frames(0, 60))

    def packets(dx: float) -> list[bytes]:
        out = []
        for t in range(seq.num_frames):
            person = np.concatenate([seq.xy[t] + (dx, 0.0), seq.confidence[t][:, None]], 1)
            person[~seq.valid[t]] = 0.0
            out.append(encode_keypoints(t, t / 30.0, [person]))
        return out

    def frames(src: UdpKeypointSource, data: list[bytes]) -> list[SourceFrame | None]:
        return [src.handle_packet(d, 0.0) for d in data]

    src = UdpKeypointSource(model, "127.0.0.1", 0, image_size=seq.image_size)
    assert all(f is not None for f in frames(src, packets(500.0)))
    after = frames(src, packets(-300.0))  # the sender restarts with the performer elsewhere
    fresh = frames(
        UdpKeypointSource(model, "127.0.0.1", 0, image_size=seq.image_size), packets(-300.0)
    )
    assert src.stats.dropped.get("no_person", 0) == 0
    for a, b in zip(after, fresh, strict=True):
        assert a is not None
        assert b is not None
        np.testing.assert_allclose(a.local_quats, b.local_quats, atol=1e-9)


def test_normalised_keypoints_on_a_pixel_image_are_warned_of(runtime: Agnostic2DRuntime) -> None:
    """Keypoints in [0, 1] with a 1280×720 image had been taken as pixels: the camera fit
    found a focal length of 2 px and the pose came out 13° off, with no word."""
    src = UdpKeypointSource(runtime, "127.0.0.1", 0, image_size=(1280.0, 720.0))
    person = _person(400.0)
    normalised = person.copy()
    normalised[:, 0] /= 1280.0
    normalised[:, 1] /= 720.0
    pixels = UdpKeypointSource(runtime, "127.0.0.1", 0, image_size=(1280.0, 720.0))
    for seq in range(1, 4):
        pixels.handle_packet(encode_keypoints(seq, seq / 30, [person]), 0.0)
        src.handle_packet(encode_keypoints(seq, seq / 30, [normalised]), 0.0)
    assert not pixels.stats.warnings  # pixels: fine
    warned = [w for w in src.stats.warnings if "normalised" in w]
    assert len(warned) == 1
    assert "1280×720 px" in warned[0]
