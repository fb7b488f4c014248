"""Input a fuzzer found to crash a source or a reader, or to pass silently (2026-11-27): each is
now a counted drop or a one-line error naming what was wrong, and the receiver goes on."""

from __future__ import annotations

import codecs
import json
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import MotionFormatError
from robot_retarget.motion.bvh import parse_bvh, read_bvh
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.sources import wire
from robot_retarget.sources.base import WARN_AFTER, SourceFrame, SourceStats
from robot_retarget.sources.keypoints import load_keypoints
from robot_retarget.sources.keypoints.errors import KeypointFormatError
from robot_retarget.sources.keypoints.wire import decode_keypoints, encode_keypoints
from robot_retarget.sources.tcp_bvh import split_header
from robot_retarget.sources.udp import UdpSource

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
CLIP = FIXTURES / "motion" / "tiny_walk.bvh"
HUGE = "1" + "0" * 400  # an integer JSON reads exactly and no float can hold


def _packet(motion: HumanMotion, seq: int, t: str, **extra: object) -> bytes:
    joints = json.dumps(motion.positions()[0].tolist())
    fields = "".join(f', "{k}": {json.dumps(v)}' for k, v in extra.items())
    return (
        f'{{"v": 1, "seq": {seq}, "t": {t}, "kind": "positions", "joints": {joints}{fields}}}'
    ).encode()


def _first_frames(src: UdpSource, timeout_s: float = 3.0) -> list[SourceFrame]:
    frames: list[SourceFrame] = []
    deadline = time.monotonic() + timeout_s
    while not frames and time.monotonic() < deadline:
        frames += src.poll(time.monotonic())
        time.sleep(0.005)
    return frames


def test_packets_that_once_killed_the_receiver_are_dropped_and_it_goes_on(
    motion: HumanMotion,
) -> None:
    """A timestamp too large for a float, a 5000-digit sequence number, a list for 'kind', a
    lone surrogate in the token: each once raised in the receiver thread and ended it for good
    (every later packet ignored). Now dropped with what was wrong; the next frame arrives."""
    poison = [
        _packet(motion, 1, HUGE),
        _packet(motion, 1, "0.1").replace(b'"seq": 1', b'"seq": ' + b"9" * 5000),
        _packet(motion, 1, "0.1").replace(b'"kind": "positions"', b'"kind": ["positions"]'),
        _packet(motion, 1, "0.1", token="\ud800"),
    ]
    says = ("timestamp is not finite", "thousands of digits", "unknown kind ['positions']",
            "token is not the one --token set")  # fmt: skip
    unit = UdpSource("127.0.0.1", 0, token="s3cret")
    for data, why in zip(poison, says, strict=True):
        assert unit.handle_packet(data, 0.0) is None
        assert any(why in m for m in unit.stats.last_messages.values()), why
    with (
        UdpSource("127.0.0.1", 0, token="s3cret") as src,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx,
    ):
        for data in poison:
            tx.sendto(data, src.address)
        tx.sendto(_packet(motion, 2, "0.2", token="s3cret"), src.address)
        frames = _first_frames(src)
    assert [f.seq for f in frames] == [2]
    assert src.stats.dropped_total == len(poison)


def test_positions_no_performer_could_have_are_dropped(motion: HumanMotion) -> None:
    far = motion.positions()[0] + 1e30
    with pytest.raises(wire.WireError, match=r"a value of 1e\+30 .*metres"):
        wire.decode(wire.encode_json(wire.KIND_POSITIONS, 1, 0.1, far))


def test_a_sender_whose_every_packet_is_wrong_is_heard_live() -> None:
    stats = SourceStats()
    heard: list[str] = []
    stats.on_warning = heard.append
    for _ in range(WARN_AFTER - 1):
        stats.drop("malformed", "'joints' must have shape (22, 3), got (21, 3)")
    assert not heard
    stats.drop("malformed", "'joints' must have shape (22, 3), got (21, 3)")
    assert len(heard) == 1
    assert "got (21, 3)" in heard[0]
    stats.accept()  # a good frame ends the run
    for _ in range(WARN_AFTER - 1):
        stats.drop("nan")
    assert len(heard) == 1
    assert "malformed 30 — the last: 'joints' must have shape" in stats.summary()


def test_keypoint_packets_with_numbers_no_float_holds_are_dropped() -> None:
    good = encode_keypoints(1, 0.1, [np.ones((17, 3))], image_size=(640, 480))
    for old, new in ((b'"t":0.1', b'"t":' + HUGE.encode()),
                     (b"[640.0,480.0]", b"[" + HUGE.encode() + b",480]"),
                     (b"[[1.0,1.0,1.0]", b"[[" + HUGE.encode() + b",1.0,1.0]")):  # fmt: skip
        assert old in good
        with pytest.raises(wire.WireError):
            decode_keypoints(good.replace(old, new), 0.3)


def _clip_text() -> str:
    return CLIP.read_text()


@pytest.mark.parametrize(
    ("change", "says"),
    [
        (lambda t: t.replace("Frame Time: ", "Frame Time: 100 #"), "0.01 frames per second"),
        (lambda t: t.replace("Frame Time: ", "Frame Time: 1e6 #"), "1e-06 frames per second"),
        (lambda t: t.replace("OFFSET 0", "OFFSET 1e30", 1), "beyond ±1e\\+07: no bone"),
    ],
)
def test_bvh_values_no_recording_has_are_named(change: object, says: str) -> None:
    text = change(_clip_text())  # type: ignore[operator]
    text = text.replace(" #", "\n#") if "#" in text else text
    lines = [ln for ln in text.splitlines() if not ln.startswith("#")]
    with pytest.raises(MotionFormatError, match=says):
        parse_bvh("\n".join(lines))


def test_a_motion_value_beyond_any_angle_or_position_names_its_line() -> None:
    head, _, motion = _clip_text().partition("MOTION")
    rows = motion.strip().splitlines()
    values = rows[3].split()
    values[4] = "1e300"
    rows[3] = " ".join(values)
    with pytest.raises(MotionFormatError, match="motion row 2, value 5 is 1e300"):
        parse_bvh(head + "MOTION\n" + "\n".join(rows))


def test_a_skeleton_no_unit_makes_a_performer_is_refused(tmp_path: Path) -> None:
    clip = read_bvh(CLIP)
    tiny = tmp_path / "tiny.bvh"
    import dataclasses

    from robot_retarget.motion.bvh import write_bvh

    small = {"offsets": clip.offsets * 1e-9, "end_site_offsets": clip.end_site_offsets * 1e-9}
    write_bvh(tiny, dataclasses.replace(clip, **small))
    with pytest.raises(MotionFormatError, match=r"tiny.bvh: the skeleton stands .* no unit"):
        load_motion(tiny)


def test_a_hierarchy_deeper_than_any_skeleton_is_an_error_not_a_recursion() -> None:
    depth = 1200
    lines = [
        "HIERARCHY",
        "ROOT J0",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 3 Xrotation Yrotation Zrotation",
    ]
    for k in range(1, depth):
        lines += [f"JOINT J{k}", "{", "OFFSET 0 1 0", "CHANNELS 3 Xrotation Yrotation Zrotation"]
    lines += ["}"] * depth + [
        "MOTION",
        "Frames: 1",
        "Frame Time: 0.01",
        " ".join(["0"] * 3 * depth),
    ]
    with pytest.raises(MotionFormatError, match="nested 201 joints deep"):
        parse_bvh("\n".join(lines))


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_bvh_written_by_windows_editors_reads(encoding: str, tmp_path: Path) -> None:
    path = tmp_path / "clip.bvh"
    path.write_bytes(_clip_text().encode(encoding))
    assert path.read_bytes().startswith((codecs.BOM_UTF8, codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
    np.testing.assert_array_equal(read_bvh(path).motion, read_bvh(CLIP).motion)


def test_tcp_bvh_header_reads_as_a_file_does() -> None:
    found = split_header("HIERARCHY\nMOTION\nFrames: 0\nFrame Time 0.01\n1 2 3")
    assert found is not None
    assert found[1] == 0.01  # no colon, as the file reader takes it
    with pytest.raises(MotionFormatError, match=r"0\.01 frames per second"):
        split_header("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 100\n")


def test_keypoint_files_that_once_raised_name_file_and_frame(tmp_path: Path) -> None:
    lines = (FIXTURES / "keypoints" / "coco17.jsonl").read_bytes().splitlines()
    cases = {
        "deep.jsonl": b"[" * 100_000,
        "utf8.jsonl": lines[0][:20] + b"\xff" + lines[0][20:],
        "digits.jsonl": b'{"people": [], "x": ' + b"9" * 5000 + b"}",
        "huge.jsonl": lines[0].replace(b"[", b"[" + HUGE.encode() + b",", 1),
    }
    says = {"deep.jsonl": "nested too deeply", "utf8.jsonl": "not UTF-8 text \\(byte 0xff",
            "digits.jsonl": "Exceeds the limit", "huge.jsonl": "frame 1:"}  # fmt: skip
    for name, bad in cases.items():
        path = tmp_path / name
        path.write_bytes(lines[0] + b"\n" + bad + b"\n")
        with pytest.raises(
            KeypointFormatError, match=f"{name}: frame 1: .*{says[name]}|{says[name]}"
        ):
            load_keypoints(path)


def test_whatever_a_packet_raises_the_receiver_counts_it_and_goes_on(
    motion: HumanMotion, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = {"n": 0}
    original = UdpSource.handle_packet

    def flaky(self: UdpSource, data: bytes, recv_s: float) -> SourceFrame | None:
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("a decoder bug")
        return original(self, data, recv_s)

    monkeypatch.setattr(UdpSource, "handle_packet", flaky)
    with (
        UdpSource("127.0.0.1", 0) as src,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx,
    ):
        tx.sendto(_packet(motion, 1, "0.1"), src.address)
        tx.sendto(_packet(motion, 2, "0.2"), src.address)
        frames = _first_frames(src)
    assert [f.seq for f in frames] == [2]
    assert "RuntimeError: a decoder bug" in src.stats.summary()


def test_a_drop_message_is_kept_to_a_line() -> None:
    stats = SourceStats()
    stats.drop("malformed", "unknown kind " + "x" * 16_000)
    assert len(stats.last_messages["malformed"]) == 200
    assert len(stats.summary()) < 400


def test_keypoint_files_with_a_byte_order_mark_read(tmp_path: Path) -> None:
    for name in ("coco17.jsonl", "mediapipe_pose.json"):
        path = tmp_path / name
        path.write_bytes(codecs.BOM_UTF8 + (FIXTURES / "keypoints" / name).read_bytes())
        assert (
            load_keypoints(path).num_frames
            == load_keypoints(FIXTURES / "keypoints" / name).num_frames
        )
    utf16 = tmp_path / "utf16.json"
    utf16.write_bytes((FIXTURES / "keypoints" / "mediapipe_pose.json").read_text().encode("utf-16"))
    with pytest.raises(KeypointFormatError, match="not UTF-8 text"):
        load_keypoints(utf16)
