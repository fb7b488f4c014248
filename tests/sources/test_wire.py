from __future__ import annotations

import contextlib
import json
import struct

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.sources import wire

finite = st.floats(-10.0, 10.0, allow_nan=False, width=32)
seqs = st.integers(0, 2**32 - 1)
times = st.floats(0.0, 1e6, allow_nan=False)
tokens = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=16)


def _positions(values: list[float]) -> np.ndarray:
    pos = np.array(values, dtype=np.float64).reshape(22, 3)
    with contextlib.suppress(wire.WireError):
        return wire.check_body(pos)
    assume(False)  # joints collapsed onto a point: refused, below
    return pos


@settings(max_examples=40)
@given(st.lists(finite, min_size=66, max_size=66), seqs, times, tokens)
def test_binary_positions_round_trip(values: list[float], seq: int, t: float, token: str) -> None:
    pos = _positions(values)
    pkt = wire.decode(wire.encode_binary(wire.KIND_POSITIONS, seq, t, pos, token=token))
    assert pkt.kind == wire.KIND_POSITIONS
    assert (pkt.seq, pkt.t_s, pkt.token) == (seq, t, token)
    np.testing.assert_allclose(pkt.values, pos, atol=1e-5)  # float32 on the wire


@settings(max_examples=40)
@given(st.lists(finite, min_size=66, max_size=66), seqs, times, tokens)
def test_json_positions_round_trip(values: list[float], seq: int, t: float, token: str) -> None:
    pos = _positions(values)
    pkt = wire.decode(wire.encode_json(wire.KIND_POSITIONS, seq, t, pos, token=token))
    assert (pkt.seq, pkt.t_s, pkt.token) == (seq, t, token)
    np.testing.assert_array_equal(pkt.values, pos)


@pytest.mark.parametrize("encode", [wire.encode_json, wire.encode_binary])
def test_rotations_round_trip(encode: object, rng: np.random.Generator) -> None:
    q = quat.normalize(rng.normal(size=(22, 4)))
    root = rng.normal(size=3)
    pkt = wire.decode(encode(wire.KIND_ROTATIONS, 5, 1.5, q, root))  # type: ignore[operator]
    np.testing.assert_allclose(pkt.values, q, atol=1e-6)
    assert pkt.root is not None
    np.testing.assert_allclose(pkt.root, root, atol=1e-6)


def test_binary_layout_is_as_documented() -> None:
    data = wire.encode_binary(wire.KIND_POSITIONS, 7, 2.5, np.zeros((22, 3)), token="ab")
    assert data[:4] == b"RRM1"
    assert struct.unpack_from("<BBHId", data, 4) == (1, 1, 2, 7, 2.5)
    assert data[20:22] == b"ab"
    assert len(data) == 22 + 66 * 4


def _reason(data: bytes) -> str:
    with pytest.raises(wire.WireError) as info:
        wire.decode(data)
    return info.value.reason


def test_malformed_packets_give_reasons() -> None:
    good = wire.encode_binary(wire.KIND_POSITIONS, 1, 0.0, np.zeros((22, 3)))
    assert _reason(good[:-4]) == "malformed"
    assert _reason(good[:10]) == "malformed"
    assert _reason(b"RRM1" + bytes([1, 9]) + good[6:]) == "malformed"  # unknown kind
    assert _reason(b"RRM1" + bytes([2]) + good[5:]) == "malformed"  # unknown version
    assert _reason(b"[1, 2, 3]") == "malformed"
    assert _reason(b"\xff\xfe") == "malformed"
    obj = {"v": 1, "seq": 1, "t": 0.0, "kind": "positions", "joints": [[0, 0]] * 22}
    assert _reason(json.dumps(obj).encode()) == "malformed"
    obj["joints"] = [[0, 0, 0]] * 22
    obj["seq"] = -1
    assert _reason(json.dumps(obj).encode()) == "malformed"
    obj["seq"] = True
    assert _reason(json.dumps(obj).encode()) == "malformed"


def test_nan_and_oversized_packets() -> None:
    pos = np.zeros((22, 3))
    pos[3, 1] = np.nan
    assert _reason(wire.encode_binary(wire.KIND_POSITIONS, 1, 0.0, pos)) == "nan"
    assert _reason(wire.encode_json(wire.KIND_POSITIONS, 1, 0.0, pos)) == "nan"
    assert _reason(wire.encode_binary(wire.KIND_POSITIONS, 1, float("inf"), np.zeros((22, 3)))) == (
        "nan"
    )
    assert _reason(b"RRM1" + b"\0" * wire.MAX_BINARY_BYTES) == "oversized"
    assert _reason(b" " * (wire.MAX_JSON_BYTES + 1)) == "oversized"


def test_joints_collapsed_onto_a_point_are_no_pose() -> None:
    """A tracker that lost the person and sends zeros: dropped like NaN (the loop holds, then
    goes to the safe pose), where it had solved to straight legs at full speed."""
    for collapsed in (np.zeros((22, 3)), np.ones((22, 3))):
        for packet in (wire.encode_binary, wire.encode_json):
            assert _reason(packet(wire.KIND_POSITIONS, 1, 0.0, collapsed)) == "degenerate"
    pose = np.cumsum(np.full((22, 3), 0.05), axis=0)  # every bone 8.7 cm
    pose[12:] = pose[12]  # a few bones collapsed (joints the tracker lost): still a pose
    assert len(wire.check_body(pose)) == 22


@settings(max_examples=200)
@given(st.binary(max_size=600))
def test_random_bytes_never_escape_as_other_errors(data: bytes) -> None:
    with contextlib.suppress(wire.WireError):
        wire.decode(data)


@settings(max_examples=100)
@given(st.binary(min_size=1, max_size=40), st.integers(0, 300))
def test_corrupted_binary_packets_are_rejected_or_valid(patch: bytes, at: int) -> None:
    good = bytearray(wire.encode_binary(wire.KIND_POSITIONS, 3, 1.0, np.ones((22, 3))))
    good[at : at + len(patch)] = patch
    try:
        pkt = wire.decode(bytes(good))
    except wire.WireError:
        return
    assert np.all(np.isfinite(pkt.values))


def test_a_signalling_nan_is_rejected_without_a_warning() -> None:
    """numpy warns when it casts a signalling NaN; the receiver thread's decode must not (the
    packet is rejected as NaN all the same)."""
    import warnings

    packet = bytearray(wire.encode_binary(wire.KIND_POSITIONS, 1, 0.0, np.zeros((22, 3))))
    packet[-4:] = struct.pack("<I", 0x7F800001)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(wire.WireError) as info:
            wire.decode(bytes(packet))
    assert info.value.reason == "nan"
