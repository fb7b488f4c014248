"""GoalPacket: the preallocated goal Sync Write is byte for byte the general packet builder's."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.goal_packet import GoalPacket


def _reference(
    protocol: float, address: int, size: int, ids: list[int], values: list[int]
) -> bytes:
    bus = DynamixelBus("/dev/null", protocol=protocol, baud_rate=1_000_000)
    return bus.sync_write_packet(
        address, size, {sid: p.le_bytes(v, size) for sid, v in zip(ids, values, strict=True)}
    )


@settings(max_examples=150)
@given(
    st.sampled_from([(2.0, 116, 4), (1.0, 30, 2), (2.0, 64, 1)]),
    st.lists(st.integers(0, 252), min_size=1, max_size=25, unique=True),
    st.data(),
)
def test_packet_equals_the_general_builder(
    layout: tuple[float, int, int], ids: list[int], data: st.DataObject
) -> None:
    protocol, address, size = layout
    half = 1 << (8 * size - 1)
    values = data.draw(st.lists(st.integers(-half, half - 1), min_size=len(ids), max_size=len(ids)))
    goal = GoalPacket(protocol, address, size, ids)
    # Built twice: the second packet must not keep anything of the first.
    goal.build(np.array(values[::-1], dtype=np.int64))
    assert goal.build(np.array(values, dtype=np.int64)) == _reference(
        protocol, address, size, ids, values
    )


def test_negative_ticks_that_need_stuffing_are_stuffed() -> None:
    # -3 = FD FF FF FF: with the next servo's ID and value this holds FF FF FD in the payload.
    ids, values = [1, 0xFD], [0x00FFFF00, -3]
    packet = GoalPacket(2.0, 116, 4, ids).build(np.array(values))
    assert packet == _reference(2.0, 116, 4, ids, values)
    assert p.parse_v2(packet).params[4:] == bytes((1,)) + p.le_bytes(values[0], 4) + bytes(
        (0xFD,)
    ) + p.le_bytes(values[1], 4)


def test_protocol1_too_many_servos_is_refused() -> None:
    with pytest.raises(ValueError, match="too long"):
        GoalPacket(1.0, 30, 2, list(range(90)))


@settings(max_examples=100)
@given(st.binary(min_size=64, max_size=1100))
def test_long_packet_crc_matches_the_bytewise_loop(data: bytes) -> None:
    # crc16_packet takes the per-position table path from 64 bytes on.
    crc = 0
    for b in data:
        crc = ((crc << 8) ^ p._CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    assert p.crc16_packet(data) == crc == p.crc16(data)
