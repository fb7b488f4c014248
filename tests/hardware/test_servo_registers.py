"""EEPROM left by other tools (pypot's angle limits, LeRobot's Homing Offset and Drive Mode):
connect refuses naming the servo and the register, or writes the expected values when asked."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.servo_registers import RegisterMismatchError, joint_tick_range
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.dxl_bus import SimulatedBus

MakeBuses = Callable[..., dict[str, DynamixelBus]]


def _servo(config: RobotConfig, sims: dict[str, SimulatedBus], joint: str):  # type: ignore[no-untyped-def]
    j = next(j for j in config.joints if j.name == joint)
    return j, sims[j.bus].servos[j.servo_id]


@pytest.mark.parametrize(
    ("register", "value"),
    [("homing_offset", 100), ("homing_offset", -2048), ("drive_mode", 1),
     ("min_position_limit", 2100), ("max_position_limit", 2000)],
)  # fmt: skip
def test_op3_refuses_a_servo_calibrated_by_another_tool(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses,
    register: str, value: int,
) -> None:  # fmt: skip
    joint, servo = _servo(op3, op3_sim, "l_knee")
    servo._put(register, value & 0xFFFFFFFF if value < 0 else value)
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), handle_signals=False)
    with pytest.raises(RegisterMismatchError) as info:
        backend.connect()
    err = info.value
    assert (err.servo_id, err.joint, err.register) == (joint.servo_id, "l_knee", register)
    assert err.found == value
    assert str(joint.servo_id) in str(err)
    assert register in str(err)
    assert not backend.connected
    assert not servo.torque_on


def test_poppy_refuses_pypot_angle_limits_and_fixes_them(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    joint, servo = _servo(poppy, poppy_sim, "r_knee_y")
    lo, hi = joint_tick_range(joint)
    servo._put("cw_angle_limit", lo + 200)  # part of the configured range refused
    servo._put("ccw_angle_limit", hi - 200)
    with pytest.raises(RegisterMismatchError, match="cw_angle_limit") as info:
        DynamixelBackend(poppy, make_buses(poppy, poppy_sim), handle_signals=False).connect()
    assert {f.register for f in info.value.findings} == {"cw_angle_limit", "ccw_angle_limit"}
    fixing = DynamixelBackend(
        poppy, make_buses(poppy, poppy_sim), handle_signals=False, fix_registers=True
    )
    fixing.connect()
    try:
        assert servo.get("cw_angle_limit") <= lo
        assert servo.get("ccw_angle_limit") >= hi
    finally:
        fixing.disconnect()


def test_wheel_mode_is_a_mismatch(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    _, servo = _servo(poppy, poppy_sim, "head_z")
    servo._put("cw_angle_limit", 0)
    servo._put("ccw_angle_limit", 0)
    with pytest.raises(RegisterMismatchError, match="wheel mode") as info:
        DynamixelBackend(poppy, make_buses(poppy, poppy_sim), handle_signals=False).connect()
    assert {f.register for f in info.value.findings} == {"cw_angle_limit", "ccw_angle_limit"}


def test_fix_writes_homing_and_drive_mode_back(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    _, servo = _servo(op3, op3_sim, "r_sho_pitch")
    servo._put("homing_offset", 512)
    servo._put("drive_mode", 0x05)  # reverse + another bit, which stays
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), handle_signals=False,
                               fix_registers=True)  # fmt: skip
    backend.connect()
    try:
        assert servo.get("homing_offset") == 0
        assert servo.get("drive_mode") == 0x04
    finally:
        backend.disconnect()


def test_a_locked_eeprom_is_not_fixed_but_explained(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    _, servo = _servo(poppy, poppy_sim, "l_elbow_y")
    servo._put("cw_angle_limit", 2040)
    servo._put("lock", 1)
    backend = DynamixelBackend(poppy, make_buses(poppy, poppy_sim), handle_signals=False,
                               fix_registers=True)  # fmt: skip
    with pytest.raises(HardwareError, match="locked"):
        backend.connect()
