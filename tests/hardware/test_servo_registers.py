"""EEPROM left by other tools (pypot's angle limits, LeRobot's Homing Offset and Drive Mode):
connect refuses naming the servo and the register, or writes the expected values when asked."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import cast

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.control_table import control_table
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.servo_registers import (
    FIX_ADVICE,
    EepromLockedError,
    RegisterMismatchError,
    RegisterWriteError,
    check_servo,
    joint_tick_range,
)
from robot_retarget.robot.config import JointConfig, RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.robot.servo_units import JointServoUnits
from robot_retarget.sim.dxl_bus import SimulatedBus
from robot_retarget.sim.servo import OK, SimServo

MakeBuses = Callable[..., dict[str, DynamixelBus]]
ROBOTS = ("op3", "poppy")  # fixture names: (config, simulated buses) = (NAME, NAME_sim)


def _robot(
    request: pytest.FixtureRequest, name: str
) -> tuple[RobotConfig, dict[str, SimulatedBus]]:
    return request.getfixturevalue(name), request.getfixturevalue(f"{name}_sim")


def _servo(
    config: RobotConfig, sims: dict[str, SimulatedBus], joint: str
) -> tuple[JointConfig, SimServo]:
    j = next(j for j in config.joints if j.name == joint)
    return j, sims[j.bus].servos[j.servo_id]


def _leftovers(joint: JointConfig) -> list[tuple[str, int]]:
    """(register, value) another tool could leave on ``joint``'s servo, each one enough to
    refuse: limits one tick inside the joint's range, any Homing Offset, the reverse bit."""
    lo, hi = joint_tick_range(joint)
    quiet = [("status_return_level", 1)]  # answers reads, not writes
    if control_table(joint.servo_model).protocol == 1.0:
        return [("cw_angle_limit", lo + 1), ("ccw_angle_limit", hi - 1), *quiet]
    return [("min_position_limit", lo + 1), ("max_position_limit", hi - 1),
            ("homing_offset", 1), ("homing_offset", -2048), ("drive_mode", 1),
            *quiet]  # fmt: skip


@pytest.mark.parametrize("robot", ROBOTS)
def test_any_leftover_on_any_servo_refuses_connect_naming_it(
    request: pytest.FixtureRequest, make_buses: MakeBuses, robot: str
) -> None:
    """Every servo of OP3 and Poppy, every register: refused, servo and register named."""
    config, sims = _robot(request, robot)
    for joint in config.joints:
        servo = sims[joint.bus].servos[joint.servo_id]
        for register, value in _leftovers(joint):
            before = servo.get(register)
            servo._put(register, value)
            backend = DynamixelBackend(config, make_buses(config, sims), handle_signals=False)
            with pytest.raises(RegisterMismatchError) as info:
                backend.connect()
            err = info.value
            assert (err.servo_id, err.joint, err.register, err.found, err.bus) == (
                joint.servo_id, joint.name, register, value, joint.bus
            )  # fmt: skip
            low, high = err.expected_range
            assert not low <= value <= high
            text = str(err)
            assert f"servo ID {joint.servo_id}" in text
            assert register in text
            assert "--fix-registers" in text
            assert not backend.connected
            assert not servo.torque_on
            servo._put(register, before)


@pytest.mark.parametrize("robot", ROBOTS)
def test_limits_exactly_the_joint_range_are_accepted(
    request: pytest.FixtureRequest, make_buses: MakeBuses, robot: str
) -> None:
    """No false refusal: the tightest limits that allow every configured angle pass."""
    config, sims = _robot(request, robot)
    for joint in config.joints:
        servo = sims[joint.bus].servos[joint.servo_id]
        lo, hi = joint_tick_range(joint)
        names = ("cw_angle_limit", "ccw_angle_limit") if servo.protocol == 1.0 else (
            "min_position_limit", "max_position_limit")  # fmt: skip
        servo._put(names[0], lo)
        servo._put(names[1], hi)
    backend = DynamixelBackend(config, make_buses(config, sims), handle_signals=False)
    backend.connect()
    backend.disconnect()


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


def _pypot_degree_to_dxl(degrees: float, model: str) -> int:
    """pypot 5.0.2 dynamixel.conversion.degree_to_dxl: MX 4096 steps over 360°, AX 1024 over
    300°, scaled by (steps − 1), no orientation or offset (what set_angle_limit writes)."""
    steps, span = (4096, 360.0) if model.startswith("MX") else (1024, 300.0)
    pos = round((steps - 1) * ((span / 2 + degrees) / span))
    return min(max(pos, 0), steps - 1)


def test_a_poppy_that_ran_pypot_is_refused_until_fixed(
    poppy: RobotConfig,
    poppy_sim: dict[str, SimulatedBus],
    make_buses: MakeBuses,
    shared_data_dir: Path,
) -> None:
    """pypot's stock Poppy JSON, its angle_limit written raw as pypot's config check does:
    connect refuses, bus by bus, every joint whose range the servo would cut; the fix writes
    them all."""
    path = shared_data_dir / "robots" / "poppy_humanoid" / "poppy_humanoid.json"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    motors = json.loads(path.read_text())["motors"]

    def run_pypot() -> set[str]:
        cut_by_more_than_a_tick = set()
        for joint in poppy.joints:
            servo = poppy_sim[joint.bus].servos[joint.servo_id]
            cw, ccw = (_pypot_degree_to_dxl(d, joint.servo_model)
                       for d in motors[joint.name]["angle_limit"])  # fmt: skip
            servo._put("cw_angle_limit", cw)
            servo._put("ccw_angle_limit", ccw)
            lo, hi = joint_tick_range(joint)
            if cw > lo + 1 or ccw < hi - 1:
                cut_by_more_than_a_tick.add(joint.name)
        return cut_by_more_than_a_tick

    cut = run_pypot()
    assert len(cut) == 13  # the README's count (9 more are cut by pypot's rounding, 1 tick)
    refused: set[str] = set()
    for _ in range(len(poppy.buses)):  # connect stops at the first bus that disagrees
        with pytest.raises(RegisterMismatchError) as info:
            DynamixelBackend(poppy, make_buses(poppy, poppy_sim), handle_signals=False).connect()
        refused |= {f.joint for f in info.value.findings}
        for f in info.value.findings:  # set that bus right by hand, to see the next one
            poppy_sim[info.value.bus].servos[f.servo_id]._put(f.register, f.expected_range[0])
    assert cut <= refused
    run_pypot()
    fixing = DynamixelBackend(
        poppy, make_buses(poppy, poppy_sim), handle_signals=False, fix_registers=True
    )
    fixing.connect()
    fixing.disconnect()
    again = DynamixelBackend(poppy, make_buses(poppy, poppy_sim), handle_signals=False)
    again.connect()  # fixed for good: no option needed any more
    again.disconnect()


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
    servo._put("max_position_limit", 3000)
    servo._put("torque_enable", 1)  # left on by the other tool: EEPROM needs it off
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), handle_signals=False,
                               fix_registers=True)  # fmt: skip
    backend.connect()
    try:
        assert servo.get("homing_offset") == 0
        assert servo.get("drive_mode") == 0x04
        assert servo.get("max_position_limit") == 4095
    finally:
        backend.disconnect()


@pytest.mark.parametrize("robot", ROBOTS)
def test_a_servo_that_answers_no_write_is_named_and_fixed(
    request: pytest.FixtureRequest, make_buses: MakeBuses, robot: str
) -> None:
    """Status Return Level 1 (answers reads only): the stream's connect timed out on its first
    write, blaming power and cabling, and doctor said OK. Now named, and fixed with a write
    that waits for no reply, then the other registers as usual."""
    config, sims = _robot(request, robot)
    _joint, servo = _servo(config, sims, config.joints[-1].name)
    servo._put("status_return_level", 1)
    servo._put("torque_enable", 1)
    backend = DynamixelBackend(config, make_buses(config, sims), handle_signals=False)
    with pytest.raises(RegisterMismatchError, match="status_return_level") as info:
        backend.connect()
    # the advice names this robot and its port (it said `doctor --robot R`)
    assert f"`robot-retarget doctor --robot {config.name} --port " in str(info.value)
    fixing = DynamixelBackend(config, make_buses(config, sims), handle_signals=False,
                              fix_registers=True)  # fmt: skip
    fixing.connect()
    try:
        assert servo.get("status_return_level") == 2
        assert fixing.connected
    finally:
        fixing.disconnect()


def test_a_value_the_servo_does_not_keep_is_reported_after_the_fix(
    op3: RobotConfig,
    op3_sim: dict[str, SimulatedBus],
    make_buses: MakeBuses,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The fix reads every register back: a servo that acknowledges but keeps its old value
    still refuses the connect, and the error says the write did not stick."""
    joint, servo = _servo(op3, op3_sim, "l_el")
    servo._put("homing_offset", 300)
    write = servo.write
    homing = servo.table["homing_offset"].address
    monkeypatch.setattr(servo, "write", lambda a, d: OK if a == homing else write(a, d))
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), handle_signals=False,
                               fix_registers=True)  # fmt: skip
    with pytest.raises(RegisterMismatchError, match="did not keep") as info:
        backend.connect()
    assert info.value.after_fix
    assert (info.value.servo_id, info.value.register, info.value.found) == (
        joint.servo_id, "homing_offset", 300
    )  # fmt: skip


def test_a_refused_write_names_servo_register_and_value(
    op3: RobotConfig,
    op3_sim: dict[str, SimulatedBus],
    make_buses: MakeBuses,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    joint, servo = _servo(op3, op3_sim, "l_el")
    servo._put("drive_mode", 1)
    write = servo.write
    drive = servo.table["drive_mode"].address
    monkeypatch.setattr(servo, "write", lambda a, d: 2 if a == drive else write(a, d))
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), handle_signals=False,
                               fix_registers=True)  # fmt: skip
    with pytest.raises(RegisterWriteError) as info:
        backend.connect()
    assert (info.value.servo_id, info.value.register, info.value.value) == (
        joint.servo_id, "drive_mode", 0
    )  # fmt: skip
    assert info.value.error == p.ERR2_DATA_LIMIT


def test_a_locked_eeprom_is_not_fixed_but_explained(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    joint, servo = _servo(poppy, poppy_sim, "l_elbow_y")
    servo._put("cw_angle_limit", 2040)
    servo._put("lock", 1)
    backend = DynamixelBackend(poppy, make_buses(poppy, poppy_sim), handle_signals=False,
                               fix_registers=True)  # fmt: skip
    with pytest.raises(EepromLockedError, match="power-cycle") as info:
        backend.connect()
    err = info.value
    assert (err.servo_id, err.joint, err.register, err.found) == (
        joint.servo_id, "l_elbow_y", "lock", 1
    )  # fmt: skip
    assert [f.register for f in err.findings] == ["cw_angle_limit"]
    assert servo.get("cw_angle_limit") == 2040  # nothing written
    assert not backend.connected


def test_the_message_tells_what_to_do() -> None:
    assert "doctor" in FIX_ADVICE
    assert "--fix-registers" in FIX_ADVICE
    assert "fix_registers=True" in FIX_ADVICE


# ----- properties: the check agrees with what the servo obeys ---------------------------------
class _MemoryBus:
    """check_servo's view of a bus, read straight from a SimServo's memory (no pty: fast)."""

    def __init__(self, servo: SimServo) -> None:
        self.servo = servo
        self.protocol = servo.protocol
        self.name = "memory"

    def read(self, servo_id: int, address: int, size: int) -> tuple[int, bytes]:
        return self.servo.read(address, size)


ALL_JOINTS = [j for name in ("op3", "poppy_humanoid") for j in load_robot_config(name).joints]


@settings(max_examples=300)
@given(
    joint=st.sampled_from(ALL_JOINTS),
    a=st.integers(0, 4095),
    b=st.integers(0, 4095),
    pick=st.floats(0.0, 1.0),
)
def test_the_limit_check_passes_exactly_when_the_servo_takes_every_configured_goal(
    joint: JointConfig, a: int, b: int, pick: float
) -> None:
    servo = SimServo(joint.servo_id, joint.servo_model)
    table = servo.table
    top = servo.model.max_tick
    a, b = min(a, top), min(b, top)
    names = (
        ("cw_angle_limit", "ccw_angle_limit")
        if "cw_angle_limit" in table
        else ("min_position_limit", "max_position_limit")
    )
    servo._put(names[0], a)
    servo._put(names[1], b)
    findings = check_servo(cast(DynamixelBus, _MemoryBus(servo)), joint, table)
    ok = all(f.ok for f in findings if f.register in names)
    lo, hi = joint_tick_range(joint)
    goal = table["goal_position"]

    def takes(tick: int) -> bool:
        return servo.write(goal.address, p.le_bytes(tick, goal.size)) == OK

    # Both limits 0 (wheel) or both 4095 on an MX (multi-turn): the servo takes any goal but
    # is no position servo there (wheel: it ignores goals), so the check must refuse it too.
    assert ok == (servo.mode() == "position" and takes(lo) and takes(hi))
    if ok:  # then every angle of the configured range lands, as the backend converts it
        q = joint.lower_rad + pick * (joint.upper_rad - joint.lower_rad)
        assert takes(JointServoUnits(joint).to_tick(q))
