"""Control-table addresses checked against the ROBOTIS e-Manual values."""

from __future__ import annotations

import itertools

import pytest

from robot_retarget.hardware.control_table import (
    CONTROL_TABLES,
    control_table,
    decode_sign_magnitude,
    error_bit_names,
)
from robot_retarget.robot.servo_models import SERVO_MODELS

# (register, address, size) from emanual.robotis.com, XM430-W350 (Protocol 2.0).
XM430 = [
    ("model_number", 0, 2),
    ("id", 7, 1),
    ("baud_rate", 8, 1),
    ("return_delay_time", 9, 1),
    ("operating_mode", 11, 1),
    ("homing_offset", 20, 4),
    ("max_position_limit", 48, 4),
    ("min_position_limit", 52, 4),
    ("torque_enable", 64, 1),
    ("hardware_error_status", 70, 1),
    ("profile_acceleration", 108, 4),
    ("profile_velocity", 112, 4),
    ("goal_position", 116, 4),
    ("present_load", 126, 2),
    ("present_velocity", 128, 4),
    ("present_position", 132, 4),
    ("present_temperature", 146, 1),
]
# MX-28 / MX-64 / AX-12A (Protocol 1.0).
P1 = [
    ("model_number", 0, 2),
    ("id", 3, 1),
    ("return_delay_time", 5, 1),
    ("cw_angle_limit", 6, 2),
    ("ccw_angle_limit", 8, 2),
    ("torque_enable", 24, 1),
    ("goal_position", 30, 2),
    ("moving_speed", 32, 2),
    ("present_position", 36, 2),
    ("present_speed", 38, 2),
    ("present_load", 40, 2),
    ("present_temperature", 43, 1),
]


@pytest.mark.parametrize(("name", "address", "size"), XM430)
def test_xm430_addresses(name: str, address: int, size: int) -> None:
    reg = control_table("XM430-W350")[name]
    assert (reg.address, reg.size) == (address, size)


@pytest.mark.parametrize("model", ["MX-28", "MX-64", "AX-12A"])
@pytest.mark.parametrize(("name", "address", "size"), P1)
def test_protocol1_addresses(model: str, name: str, address: int, size: int) -> None:
    reg = control_table(model)[name]
    assert (reg.address, reg.size) == (address, size)


def test_every_servo_model_has_a_table_with_its_model_number() -> None:
    for name, model in SERVO_MODELS.items():
        table = control_table(name)
        assert table["model_number"].default == model.model_number
        assert table.protocol in model.protocols


def test_eeprom_and_access_flags() -> None:
    xm = control_table("XM430-W350")
    assert xm["operating_mode"].eeprom
    assert not xm["goal_position"].eeprom
    assert not xm["present_position"].writable
    assert not xm["model_number"].writable
    for table in CONTROL_TABLES.values():
        addresses = sorted((r.address, r.address + r.size) for r in table.registers.values())
        for (a0, a1), (b0, _) in itertools.pairwise(addresses):
            assert a1 <= b0, f"{table.model}: overlapping registers at {a0} and {b0}"
        assert addresses[-1][1] <= table.memory_size


def test_present_blocks() -> None:
    assert control_table("XM430-W350").block("present_load", "present_temperature") == (126, 21)
    assert control_table("MX-28").block("present_position", "present_temperature") == (36, 8)


def test_unknown_names_list_alternatives() -> None:
    with pytest.raises(KeyError, match="known"):
        control_table("XL-320")
    with pytest.raises(KeyError, match="registers"):
        control_table("MX-28")["goal_velocity"]


def test_error_bits_and_units() -> None:
    assert error_bit_names(0x24, 2.0) == ("overheating", "overload")
    assert error_bit_names(0x18, 2.0) == ("motor encoder", "electrical shock")
    assert error_bit_names(0x21, 1.0) == ("input voltage", "overload")
    assert decode_sign_magnitude(1024 + 5, 10) == -5
    assert decode_sign_magnitude(5, 10) == 5
    assert control_table("XM430-W350").velocity_unit_rad_s == pytest.approx(0.229 * 0.10471976)
