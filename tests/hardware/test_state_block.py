"""StateBlock: registers decoded by name from the control table, for many servos at once."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.hardware.control_table import (
    AX_12A,
    MX_28,
    MX_64,
    XM430_W350,
    ControlTable,
    decode_sign_magnitude,
)
from robot_retarget.hardware.state_block import StateBlock, stack_blocks

V2 = ("present_load", "present_velocity", "present_position")
V1 = ("present_position", "present_speed", "present_load", "present_temperature")


def _one(table: ControlTable, block: StateBlock, raw: bytes, name: str) -> int:
    reg = table[name]
    chunk = raw[reg.address - block.address : reg.address - block.address + reg.size]
    value = int.from_bytes(chunk, "little", signed=reg.signed)
    if table.sign_magnitude_bit is not None and name in ("present_speed", "present_load"):
        return decode_sign_magnitude(value, table.sign_magnitude_bit)
    return value


def test_span_and_places_come_from_the_table() -> None:
    block = StateBlock(XM430_W350, V2)
    assert (block.address, block.size) == (126, 10)  # Present Load 126 … Present Position 135
    assert StateBlock(MX_28, V1).size == 8  # 36 … 43
    assert StateBlock(MX_28, V1).matches(AX_12A)
    assert StateBlock(MX_28, V1).matches(MX_64)
    assert not StateBlock(XM430_W350, V2).matches(MX_28)


@settings(max_examples=100)
@given(st.sampled_from([(XM430_W350, V2), (MX_28, V1), (AX_12A, V1)]), st.data())
def test_decode_equals_one_register_at_a_time(
    layout: tuple[ControlTable, tuple[str, ...]], data: st.DataObject
) -> None:
    table, names = layout
    block = StateBlock(table, names)
    rows = data.draw(st.lists(st.binary(min_size=block.size, max_size=block.size), min_size=1))
    matrix = stack_blocks(rows, block.size)
    for name in names:
        got = block.decode(matrix, name)
        assert got.dtype == np.int64
        assert got.tolist() == [_one(table, block, r, name) for r in rows]


def test_unknown_register_names_the_model() -> None:
    with pytest.raises(KeyError, match="XM430-W350 has no register 'present_speed'"):
        StateBlock(XM430_W350, ("present_speed",))
