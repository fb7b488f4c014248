from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import SourceError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.sources.base import SourceFrame
from robot_retarget.sources.tcp_bvh import TcpBvhSource, split_header

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"

CLIP = FIXTURES / "tiny_walk.bvh"


@contextmanager
def bvh_server(chunks: list[bytes], pause_s: float = 0.0) -> Iterator[int]:
    """A one-connection TCP server on 127.0.0.1 sending ``chunks``; yields its port."""
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(5.0)

    def serve() -> None:
        try:
            conn, _ = srv.accept()
        except OSError:
            return
        with conn:
            for c in chunks:
                conn.sendall(c)
                if pause_s:
                    time.sleep(pause_s)
            time.sleep(0.3)  # let the client read before the close

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield srv.getsockname()[1]
    finally:
        srv.close()
        t.join(timeout=5.0)


def _split_file() -> tuple[bytes, list[bytes]]:
    text = CLIP.read_text()
    head, _, motion = text.partition("MOTION")
    lines = motion.strip().splitlines()
    header = (head + "MOTION\n" + lines[0] + "\n" + lines[1] + "\n").encode()
    return header, [(ln + "\n").encode() for ln in lines[2:]]


def _collect(src: TcpBvhSource, count: int, timeout_s: float = 5.0) -> list[SourceFrame]:
    out: list[SourceFrame] = []
    deadline = time.monotonic() + timeout_s
    while len(out) < count and time.monotonic() < deadline:
        out += src.poll(time.monotonic())
        time.sleep(0.01)
    return out


def _wait_finished(src: TcpBvhSource, timeout_s: float = 3.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not src.finished and time.monotonic() < deadline:
        time.sleep(0.02)


def test_stream_matches_the_file_loader() -> None:
    header, rows = _split_file()
    # Header and rows split at awkward places, as TCP may deliver them.
    blob = header + b"".join(rows)
    chunks = [blob[i : i + 97] for i in range(0, len(blob), 97)]
    with bvh_server(chunks) as port:
        src = TcpBvhSource("127.0.0.1", port)
        with src:
            frames = _collect(src, len(rows))
    ref = load_motion(CLIP, drop_tpose=False)
    assert len(frames) == ref.num_frames
    assert [f.seq for f in frames] == list(range(ref.num_frames))
    got = np.array([f.local_quats for f in frames])
    dots = np.abs(np.sum(got * ref.local_quats, axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-9)
    np.testing.assert_allclose(np.array([f.root_pos for f in frames]), ref.root_pos, atol=1e-9)
    np.testing.assert_allclose(src.skeleton.offsets, ref.skeleton.offsets, atol=1e-12)
    assert src.nominal_fps == pytest.approx(30.0)
    assert frames[1].t_s == pytest.approx(1 / 30)


def test_bad_lines_are_dropped_and_counted() -> None:
    header, rows = _split_file()
    width = len(rows[0].split())
    bad = [b"1 2 3\n", b"x" * 10 + b"\n", (" ".join(["nan"] * width) + "\n").encode()]
    with bvh_server([header, rows[0], *bad, rows[1]], pause_s=0.02) as port:
        src = TcpBvhSource("127.0.0.1", port)
        with src:
            frames = _collect(src, 2)
            _wait_finished(src)
    assert len(frames) == 2
    assert src.stats.dropped["malformed"] == 2
    assert src.stats.dropped["nan"] == 1
    assert src.finished
    assert src.error is not None
    assert np.all(np.isfinite(quat.normalize(frames[1].local_quats)))


def test_no_header_is_a_source_error() -> None:
    with bvh_server([b"HIERARCHY\nROOT Hips\n{\n"]) as port:
        src = TcpBvhSource("127.0.0.1", port, connect_timeout_s=0.5)
        with pytest.raises(SourceError):
            src.start()


def test_nobody_listening_is_a_source_error() -> None:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    with pytest.raises(SourceError, match="cannot connect"):
        TcpBvhSource("127.0.0.1", port, connect_timeout_s=0.5).start()


def test_remote_host_needs_explicit_flag() -> None:
    with pytest.raises(SourceError, match="allow-remote"):
        TcpBvhSource("10.1.2.3", 7001)


def test_split_header_waits_for_frame_time() -> None:
    assert split_header("HIERARCHY\nMOTION\nFrames: 0\n") is None
    found = split_header("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.01\n1 2 3")
    assert found is not None
    header, dt, _consumed = found
    assert header.endswith("MOTION\n")
    assert dt == 0.01


def test_a_huge_channel_count_is_refused_before_any_row_is_built() -> None:
    """CHANNELS 9999999999 once built a dummy row of that many values (a MemoryError)."""
    header, _rows = _split_file()
    assert b"CHANNELS 3" in header
    with bvh_server([header.replace(b"CHANNELS 3", b"CHANNELS 9999999999", 1)]) as port:
        src = TcpBvhSource("127.0.0.1", port, connect_timeout_s=2.0)
        with pytest.raises(SourceError, match="CHANNELS says 9999999999 channels but lists 3"):
            src.start()


def test_a_sender_that_hangs_up_mid_frame_is_reported() -> None:
    header, rows = _split_file()
    with bvh_server([header, rows[0], rows[1][:10]]) as port:
        src = TcpBvhSource("127.0.0.1", port)
        with src:
            frames = _collect(src, 1)
            _wait_finished(src)
    assert len(frames) == 1
    assert "the sender closed the stream; its last frame was cut short" in src.stats.summary()


def _warnings_of_a_sender_at(speed: float) -> list[str]:
    """400 frames fed ``speed`` times as fast as their Frame Time: the source's warnings."""
    header, rows = _split_file()
    with bvh_server([header]) as port:
        src = TcpBvhSource("127.0.0.1", port)
        with src:
            dt = src._dt
            for k, row in enumerate((rows * 20)[:400]):
                src.feed(row, 100.0 + k * dt / speed)
    return src.stats.warnings


def test_a_sender_faster_than_its_frame_time_is_warned_of() -> None:
    """Frames are stamped k · Frame Time: a sender at three times that ran the performer three
    times as fast, with no word (the safety report blamed a late loop)."""
    warned = [w for w in _warnings_of_a_sender_at(3.0) if "faster than their Frame Time" in w]
    assert len(warned) == 1
    assert "3.0×" in warned[0]


def test_a_sender_at_its_frame_time_is_not_warned_of() -> None:
    assert not [w for w in _warnings_of_a_sender_at(1.0) if "Frame Time" in w]
