"""SimServo memory, access rules and motion."""

from __future__ import annotations

import pytest

from robot_retarget.sim.servo import ACCESS_ERROR, DATA_LIMIT_ERROR, OK, SimServo


def test_memory_starts_at_factory_defaults() -> None:
    s = SimServo(7, "XM430-W350")
    assert (s.get("model_number"), s.get("id"), s.get("return_delay_time")) == (1020, 7, 250)
    ax = SimServo(36, "AX-12A")
    assert (ax.get("model_number"), ax.get("ccw_angle_limit")) == (12, 1023)


def test_torque_moves_the_horn_within_speed() -> None:
    s = SimServo(1, "MX-28")
    assert s.write(30, (3048).to_bytes(2, "little")) == OK
    s.advance(0.1)
    assert s.get("present_position") == 2048  # torque off: nothing moves
    assert s.write(24, b"\x01") == OK
    s.advance(0.1)
    moved_rad = s.present_rad
    assert 0 < moved_rad <= s.model.no_load_speed_rad_s * 0.1 + 1e-9
    assert s.get("present_speed") > 0
    assert s.get("moving") == 1


def test_access_rules() -> None:
    s = SimServo(1, "XM430-W350")
    assert s.write(132, bytes(4)) == ACCESS_ERROR
    assert s.write(116, (5000).to_bytes(4, "little")) == DATA_LIMIT_ERROR
    assert s.write(64, b"\x01") == OK
    assert s.write(11, b"\x04") == ACCESS_ERROR  # EEPROM with torque on
    assert s.read(140, 20) == (ACCESS_ERROR, b"")


@pytest.mark.parametrize("model", ["XM430-W350", "MX-28", "MX-64", "AX-12A"])
def test_set_present_round_trips(model: str) -> None:
    s = SimServo(1, model)
    s.set_present_rad(0.5)
    assert abs(s.ticks_to_rad(s.get("present_position")) - 0.5) <= s.model.rad_per_tick
    assert s.goal_rad == pytest.approx(s.ticks_to_rad(s.get("present_position")))
