from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from robot_retarget.errors import SourceError
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.sources import wire
from robot_retarget.sources.base import SourceFrame
from robot_retarget.sources.udp import UdpSource
from robot_retarget.sources.udp_datagram import is_loopback


def _wait_frames(src: UdpSource, count: int, timeout_s: float = 3.0) -> list[SourceFrame]:
    out: list[SourceFrame] = []
    deadline = time.monotonic() + timeout_s
    while len(out) < count and time.monotonic() < deadline:
        out += src.poll(time.monotonic())
        time.sleep(0.005)
    return out


def test_receives_json_and_binary_over_loopback(motion: HumanMotion) -> None:
    with UdpSource("127.0.0.1", 0) as src, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        assert isinstance(src, UdpSource)
        addr = src.address
        pos = motion.positions()
        tx.sendto(wire.encode_json(wire.KIND_POSITIONS, 1, 0.01, pos[0]), addr)
        tx.sendto(wire.encode_binary(wire.KIND_POSITIONS, 2, 0.02, pos[1]), addr)
        tx.sendto(
            wire.encode_binary(
                wire.KIND_ROTATIONS, 3, 0.03, motion.local_quats[2], motion.root_pos[2]
            ),
            addr,
        )
        frames = _wait_frames(src, 3)
    assert [f.seq for f in frames] == [1, 2, 3]
    np.testing.assert_allclose(frames[0].root_pos, motion.root_pos[0], atol=1e-9)
    np.testing.assert_allclose(frames[2].local_quats, motion.local_quats[2], atol=1e-6)
    assert src.stats.accepted == 3


def test_bad_packets_are_dropped_and_counted(motion: HumanMotion) -> None:
    src = UdpSource("127.0.0.1", 0, token="s3cret")
    pos = motion.positions()[0]
    good = wire.encode_json(wire.KIND_POSITIONS, 10, 1.0, pos, token="s3cret")
    assert src.handle_packet(good, 0.0) is not None
    nan = pos.copy()
    nan[0, 0] = np.nan
    cases = {
        "duplicate": good,
        "out_of_order": wire.encode_json(wire.KIND_POSITIONS, 9, 0.5, pos, token="s3cret"),
        "auth": wire.encode_json(wire.KIND_POSITIONS, 11, 1.1, pos, token="wrong"),
        "nan": wire.encode_binary(wire.KIND_POSITIONS, 12, 1.2, nan, token="s3cret"),
        "oversized": b"{" + b" " * 20000 + b"}",
        "malformed": b"\x00garbage",
    }
    for reason, data in cases.items():
        assert src.handle_packet(data, 0.0) is None, reason
        assert src.stats.dropped[reason] >= 1, reason
    no_token = wire.encode_json(wire.KIND_POSITIONS, 13, 1.3, pos)
    assert src.handle_packet(no_token, 0.0) is None
    assert src.stats.dropped["auth"] == 2
    bad_quat = np.zeros((22, 4))
    data = wire.encode_json(wire.KIND_ROTATIONS, 14, 1.4, bad_quat, np.zeros(3), token="s3cret")
    assert src.handle_packet(data, 0.0) is None
    assert src.stats.accepted == 1
    assert src.stats.dropped_total == src.stats.received - 1


def test_restart_with_sequence_zero_is_accepted(motion: HumanMotion) -> None:
    src = UdpSource("127.0.0.1", 0)
    pos = motion.positions()[0]
    assert src.handle_packet(wire.encode_json("positions", 50, 100.0, pos), 0.0) is not None
    assert src.handle_packet(wire.encode_json("positions", 0, 0.0, pos), 0.0) is not None


def test_restart_with_a_small_sequence_number_and_a_new_clock(motion: HumanMotion) -> None:
    src = UdpSource("127.0.0.1", 0)
    live: list[str] = []
    src.stats.on_warning = live.append
    pos = motion.positions()[0]
    for k in range(1200, 1205):
        assert src.handle_packet(wire.encode_json("positions", k, k / 60, pos), 0.0) is not None
    # The sender restarted: its first packets got lost, its sequence resumes at 2, its clock
    # restarted at 0 (both went back): a new stream, accepted from this packet.
    frame = src.handle_packet(wire.encode_json("positions", 2, 0.033, pos), 0.0)
    assert frame is not None
    assert frame.seq == 2
    assert src.stats.dropped["out_of_order"] == 0
    # A sender that restarts its sequence but keeps its clock: dropped, with a live warning.
    for k in range(3, 40):
        assert src.handle_packet(wire.encode_json("positions", k, 1.0 + k / 60, pos), 0.0)
    for k in range(1, 31):
        assert src.handle_packet(wire.encode_json("positions", k, 2.0 + k / 60, pos), 0.0) is None
    assert len(live) == 1
    assert "dropped as out of order" in live[0]
    assert src.stats.warnings == live


def test_full_queue_drops_the_oldest(motion: HumanMotion) -> None:
    src = UdpSource("127.0.0.1", 0, max_queue=4)
    pos = motion.positions()[0]
    for k in range(1, 7):
        src.handle_packet(wire.encode_binary("positions", k, k * 0.01, pos), 0.0)
    frames = src.poll(0.0)
    assert [f.seq for f in frames] == [3, 4, 5, 6]
    assert src.stats.dropped["queue_full"] == 2


def test_remote_bind_needs_explicit_flag() -> None:
    with pytest.raises(SourceError, match="allow-remote"):
        UdpSource("0.0.0.0", 0)
    UdpSource("0.0.0.0", 0, allow_remote=True)  # allowed when asked for; not started
    assert is_loopback("127.0.0.1")
    assert is_loopback("::1")
    assert is_loopback("localhost")
    assert not is_loopback("192.168.1.4")
    assert not is_loopback("example.org")


def test_port_in_use_is_a_source_error() -> None:
    with UdpSource("127.0.0.1", 0) as first:
        assert isinstance(first, UdpSource)
        second = UdpSource("127.0.0.1", first.address[1])
        with pytest.raises(SourceError, match=r"cannot bind.*is another stream running"):
            second.start()
        port = first.address[1]
    assert first.address == ("127.0.0.1", port) != ("127.0.0.1", 0)  # known after it stops


def test_an_address_not_of_this_machine_says_so() -> None:
    # TEST-NET-1 (RFC 5737): never one of this machine's addresses
    with pytest.raises(SourceError, match="not one of this machine's") as info:
        UdpSource("192.0.2.1", 0, allow_remote=True).start()
    assert "another stream" not in str(info.value)
