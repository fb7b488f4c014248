"""SimServo memory, access rules and motion."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.robot.config import JointConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.robot.servo_units import JointServoUnits
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
    assert s.read(650, 20) == (ACCESS_ERROR, b"")  # past the table's end (661)


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


def test_reverse_and_homing_together_the_offset_keeps_its_sign() -> None:
    """e-Manual: in reverse mode the sign of Homing Offset is not reversed."""
    servo = SimServo(1, "XM430-W350")
    servo._put("drive_mode", 1)
    servo._put("homing_offset", 100)
    _settle(servo, 2048 + 100 + 50)  # 50 ticks past the shifted centre, mirrored
    assert servo.present_rad == pytest.approx(-50 * servo.model.rad_per_tick, abs=2e-3)
    assert servo.get("present_position") == pytest.approx(2198, abs=1)


def test_a_homing_offset_beyond_one_quarter_turn_is_ignored_in_position_mode() -> None:
    """e-Manual: in Position Control Mode only −1024 … 1024 applies; extended mode takes any."""
    servo = SimServo(1, "XM430-W350")
    servo._put("homing_offset", 1500)
    servo.advance(0.01)
    assert servo.get("present_position") == 2048
    servo._put("homing_offset", -1024)
    servo.advance(0.01)
    assert servo.get("present_position") == 1024
    servo._put("homing_offset", 1500)
    servo._put("operating_mode", 4)  # extended position
    servo.advance(0.01)
    assert servo.get("present_position") == 2048 + 1500


@settings(max_examples=200)
@given(
    joint=st.sampled_from(load_robot_config("op3").joints),
    fraction=st.floats(0.0, 1.0),
    homing=st.integers(-1024, 1024),
    reverse=st.booleans(),
)
def test_rad_to_ticks_through_homing_and_reverse_and_back(
    joint: JointConfig, fraction: float, homing: int, reverse: bool
) -> None:
    """A joint angle → the backend's tick → the horn of a servo calibrated elsewhere → the
    tick it reports → the same angle; and the horn sits where the e-Manual's formula says."""
    q = joint.lower_rad + fraction * (joint.upper_rad - joint.lower_rad)
    units = JointServoUnits(joint)
    tick = units.to_tick(q)
    servo = SimServo(joint.servo_id, joint.servo_model)
    servo._put("homing_offset", homing)
    servo._put("drive_mode", int(reverse))
    horn = servo.horn_from_user(tick)
    assert servo.user_from_horn(horn) == tick
    assert abs(units.from_tick(servo.user_from_horn(horn)) - q) <= servo.model.rad_per_tick / 2
    # Present = mirror(horn) + offset: the horn sits (tick − offset) from the centre, mirrored.
    sign = -1 if reverse else 1
    assert horn - 2048 == sign * (tick - homing - 2048)
    servo.set_present_rad(servo.ticks_to_rad(horn))
    assert servo.get("present_position") == tick
