"""Packet layer: known vectors from the e-Manual, SDK cross-checks and hypothesis round trips."""

from __future__ import annotations

import dynamixel_sdk as sdk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.hardware import protocol as p

ids = st.integers(0, 0xFE)
payloads = st.binary(max_size=200)
# Payloads rich in FF/FD so stuffing actually happens.
tricky = st.lists(st.sampled_from([0xFF, 0xFD, 0x00, 0x01]), max_size=60).map(bytes)


def test_ping_packets_match_the_emanual() -> None:
    # Protocol 2.0 e-Manual, "Ping" example 1: ID 1.
    assert p.build_v2(1, p.INST_PING) == bytes.fromhex("FFFFFD0001030001194E")
    # Protocol 1.0 e-Manual, ping ID 1: checksum FB.
    assert p.build_v1(1, p.INST_PING) == bytes.fromhex("FFFF010201FB")


def test_read_packet_matches_the_emanual() -> None:
    # Protocol 2.0 e-Manual, "Read" example: ID 1, address 132, 4 bytes.
    params = p.le_bytes(132, 2) + p.le_bytes(4, 2)
    assert p.build_v2(1, p.INST_READ, params) == bytes.fromhex("FFFFFD0001070002840004001D15")


@settings(max_examples=200)
@given(st.binary(max_size=300))
def test_crc_matches_the_sdk_table(data: bytes) -> None:
    ref = sdk.Protocol2PacketHandler().updateCRC(0, list(data), len(data))
    assert p.crc16(data) == ref


@settings(max_examples=200)
@given(ids, st.integers(0, 255), st.binary(max_size=250))
def test_checksum_v1(servo_id: int, inst: int, params: bytes) -> None:
    body = bytes((servo_id, len(params) + 2, inst)) + params
    assert p.checksum_v1(body) == (~(sum(body) & 0xFF)) & 0xFF
    assert (sum(body) + p.checksum_v1(body)) & 0xFF == 0xFF


@settings(max_examples=300)
@given(st.one_of(payloads, tricky))
def test_stuffing_round_trip(region: bytes) -> None:
    stuffed = p.stuff(region)
    assert p.unstuff(stuffed) == region
    # After stuffing, every FF FF FD is followed by the stuffing FD.
    i = stuffed.find(b"\xff\xff\xfd")
    while i >= 0:
        assert stuffed[i + 3 : i + 4] == b"\xfd"
        i = stuffed.find(b"\xff\xff\xfd", i + 4)


@settings(max_examples=300)
@given(tricky)
def test_stuffing_agrees_with_the_sdk_add_stuffing(params: bytes) -> None:
    # addStuffing computes the right bytes (it is txPacket that drops them).
    region = bytes((p.INST_WRITE,)) + params
    length = len(region) + 2
    pkt = [0xFF, 0xFF, 0xFD, 0x00, 1, length & 0xFF, length >> 8, *region, 0, 0]
    ref = sdk.Protocol2PacketHandler().addStuffing(pkt)
    out_len = ref[5] | ref[6] << 8
    assert bytes(ref[7 : 7 + out_len - 2]) == p.stuff(region)


@settings(max_examples=300)
@given(ids, st.integers(0, 0xFF).filter(lambda i: i != p.INST_STATUS), st.one_of(payloads, tricky))
def test_v2_instruction_round_trip(servo_id: int, inst: int, params: bytes) -> None:
    pkt = p.parse_v2(p.build_v2(servo_id, inst, params))
    assert (pkt.servo_id, pkt.code, pkt.params, pkt.is_status) == (servo_id, inst, params, False)


@settings(max_examples=300)
@given(ids, st.integers(0, 0xFF), st.one_of(payloads, tricky))
def test_v2_status_round_trip(servo_id: int, error: int, params: bytes) -> None:
    raw = p.build_status_v2(servo_id, error, params)
    pkt = p.parse_v2(raw)
    assert (pkt.servo_id, pkt.code, pkt.params, pkt.is_status) == (servo_id, error, params, True)
    assert p.packet_length_v2(raw) == len(raw)


@settings(max_examples=300)
@given(ids, st.integers(0, 0xFF), st.binary(max_size=250))
def test_v1_round_trip(servo_id: int, code: int, params: bytes) -> None:
    raw = p.build_v1(servo_id, code, params)
    pkt = p.parse_v1(raw, status=True)
    assert (pkt.servo_id, pkt.code, pkt.params) == (servo_id, code, params)
    assert p.packet_length_v1(raw) == len(raw)


@settings(max_examples=200)
@given(ids, st.binary(min_size=1, max_size=40), st.data())
def test_any_single_byte_corruption_is_detected_v2(
    servo_id: int, params: bytes, data: st.DataObject
) -> None:
    raw = bytearray(p.build_v2(servo_id, p.INST_WRITE, params))
    i = data.draw(st.integers(7, len(raw) - 1))  # body and CRC (the header is framing)
    raw[i] ^= data.draw(st.integers(1, 255))
    with pytest.raises(p.MalformedPacketError):
        p.parse_v2(bytes(raw))


@settings(max_examples=200)
@given(ids, st.binary(min_size=1, max_size=40), st.data())
def test_any_single_byte_corruption_is_detected_v1(
    servo_id: int, params: bytes, data: st.DataObject
) -> None:
    raw = bytearray(p.build_v1(servo_id, p.INST_WRITE, params))
    i = data.draw(st.integers(4, len(raw) - 1))
    raw[i] ^= data.draw(st.integers(1, 255))
    with pytest.raises(p.MalformedPacketError):
        p.parse_v1(bytes(raw), status=False)


def test_unstuffed_packet_is_malformed() -> None:
    params = b"\x74\x00\xff\xff\xfd\xff"  # goal -131073 ticks: FF FF FD in the payload
    region = bytes((p.INST_WRITE,)) + params
    length = len(region) + 2
    head = p.HEADER_V2 + bytes((1, length, 0)) + region
    crc = p.crc16(head)
    with pytest.raises(p.MalformedPacketError, match="stuffing"):
        p.parse_v2(head + bytes((crc & 0xFF, crc >> 8)))


def test_find_header() -> None:
    assert p.find_header(b"\x00\x01\xff\xff\xfd\x00\x01", 2.0) == 2
    assert p.find_header(b"\x00\x01\xff\xff", 2.0) == 2  # keep a possible prefix
    assert p.find_header(b"\x00\x01\x02", 2.0) == 3
    assert p.find_header(b"\x00\xff\xff\xff\x01", 1.0) == 2
    assert p.find_header(b"\x00\x02", 1.0) == 2


def test_le_bytes_round_trip() -> None:
    for v, size in ((-131073, 4), (4095, 4), (-1, 2), (255, 1)):
        assert p.from_le(p.le_bytes(v, size), signed=v < 0) == v
    assert p.le_bytes(-131073, 4) == b"\xff\xff\xfd\xff"
