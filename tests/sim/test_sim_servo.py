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


def _settle(servo: SimServo, goal: int) -> None:
    servo._put("torque_enable", 1)
    assert servo.write(servo.table["goal_position"].address, goal.to_bytes(4, "little")) == OK
    for _ in range(200):
        servo.advance(0.01)


def test_homing_offset_shifts_where_a_goal_puts_the_horn() -> None:
    """XM430: Present Position = horn + Homing Offset; a goal lands Homing Offset away."""
    servo = SimServo(1, "XM430-W350")
    servo._put("homing_offset", 100)
    _settle(servo, 2148)
    assert servo.present_rad == pytest.approx(0.0, abs=2e-3)  # the horn sits at its centre
    assert servo.get("present_position") == pytest.approx(2148, abs=1)


def test_reverse_drive_mode_mirrors_the_horn() -> None:
    servo = SimServo(1, "XM430-W350")
    servo._put("drive_mode", 1)
    _settle(servo, 2048 + 100)
    assert servo.present_rad == pytest.approx(-100 * servo.model.rad_per_tick, abs=2e-3)
    assert servo.get("present_position") == pytest.approx(2148, abs=1)


@pytest.mark.parametrize("model", ["MX-28", "MX-64", "AX-12A"])
def test_lock_makes_the_eeprom_read_only_until_power_off(model: str) -> None:
    servo = SimServo(11, model)
    cw = servo.table["cw_angle_limit"]
    lock = servo.table["lock"]
    assert servo.write(cw.address, (100).to_bytes(2, "little")) == OK  # unlocked: fine
    assert servo.write(lock.address, b"\x01") == OK
    assert servo.write(cw.address, (0).to_bytes(2, "little")) == ACCESS_ERROR
    assert servo.write(lock.address, b"\x00") == ACCESS_ERROR  # cannot be cleared
    goal = servo.table["goal_position"]
    assert servo.write(goal.address, (512).to_bytes(2, "little")) == OK  # RAM still writable
    assert SimServo(11, model).get("lock") == 0  # power-cycled
