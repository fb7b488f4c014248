"""Servo EEPROM that other tools may have left behind, checked against the robot config.

A servo keeps its EEPROM across tools. Three kinds of leftovers silently change what a goal
position means or whether it is obeyed:

- **angle / position limits** (Protocol 1.0 CW/CCW Angle Limit, Protocol 2.0 Min/Max Position
  Limit): a goal outside them is refused by the servo — silently under Sync Write. pypot writes
  its JSON ``angle_limit`` into them; on a Poppy that has run pypot 13 of 25 joints would
  refuse part of their configured range. Both limits 0 on Protocol 1.0 is wheel mode.
- **Homing Offset** (Protocol 2.0): added by the servo to Present Position (and so to where a
  goal lands); LeRobot's calibration writes it.
- **Drive Mode bit 0, reverse** (Protocol 2.0): mirrors the direction of rotation; LeRobot's
  calibration writes it too. The config's ``direction`` already handles a joint's sign.

What this project expects: limits that contain every tick the config's joint range can command
(the fix writes the model's full range, as ROBOTIS' own OP3 framework does), Homing Offset 0,
the reverse bit 0. :func:`check_servo` reads the registers and reports each as a
:class:`RegisterFinding`; the backend refuses to connect on any mismatch unless told to fix.
"""

from __future__ import annotations

from dataclasses import dataclass

from robot_retarget.errors import HardwareError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.control_table import ControlTable
from robot_retarget.robot.config import JointConfig
from robot_retarget.robot.servo_units import JointServoUnits

_REVERSE_BIT = 0x01


@dataclass(frozen=True)
class RegisterFinding:
    """One register of one servo: what was found, what is expected, and what a fix writes."""

    servo_id: int
    joint: str
    register: str
    found: int
    expected: str
    ok: bool
    fix: int | None  # value to write, None when nothing is to be written

    def line(self) -> str:
        state = "ok" if self.ok else "MISMATCH"
        return (
            f"ID {self.servo_id} ({self.joint}) {self.register} = {self.found}: {state} "
            f"(expected {self.expected})"
        )


class RegisterMismatchError(HardwareError):
    """A servo's EEPROM disagrees with the config. Attributes name the servo, the register,
    the value found and what is expected; ``findings`` holds every mismatch found."""

    def __init__(self, findings: list[RegisterFinding], bus: str) -> None:
        first = findings[0]
        self.servo_id = first.servo_id
        self.joint = first.joint
        self.register = first.register
        self.found = first.found
        self.expected = first.expected
        self.findings = findings
        more = f" (and {len(findings) - 1} more)" if len(findings) > 1 else ""
        super().__init__(
            f"servo ID {first.servo_id} (joint {first.joint}) on bus {bus}: {first.register} = "
            f"{first.found}, expected {first.expected}{more}. Another tool left it there; "
            "nothing was moved. Run `robot-retarget doctor` to see every register, then "
            "`doctor --fix-registers` (or DynamixelBackend(..., fix_registers=True)) to write "
            "the expected values"
        )


def _read(bus: DynamixelBus, sid: int, table: ControlTable, name: str, signed: bool) -> int:
    reg = table[name]
    _err, data = bus.read(sid, reg.address, reg.size)
    return p.from_le(data, signed=signed)


def joint_tick_range(joint: JointConfig) -> tuple[int, int]:
    """The lowest and highest tick the config's joint range commands."""
    units = JointServoUnits(joint)
    a, b = units.to_tick(joint.lower_rad), units.to_tick(joint.upper_rad)
    return min(a, b), max(a, b)


def check_servo(
    bus: DynamixelBus, joint: JointConfig, table: ControlTable
) -> list[RegisterFinding]:
    """Read and judge the limit, homing and drive-mode registers of ``joint``'s servo."""
    sid = joint.servo_id
    lo, hi = joint_tick_range(joint)
    model = JointServoUnits(joint).model
    out: list[RegisterFinding] = []

    def add(register: str, found: int, expected: str, ok: bool, fix: int) -> None:
        out.append(
            RegisterFinding(sid, joint.name, register, found, expected, ok, None if ok else fix)
        )

    if "cw_angle_limit" in table:  # Protocol 1.0 (AX, MX)
        cw = _read(bus, sid, table, "cw_angle_limit", signed=False)
        ccw = _read(bus, sid, table, "ccw_angle_limit", signed=False)
        joint_mode = not (cw == 0 and ccw == 0)  # both 0: wheel mode, no position control
        wheel = "" if joint_mode else ", not wheel mode (CW = CCW = 0)"
        add("cw_angle_limit", cw, f"≤ {lo} (joint range {lo}…{hi}{wheel})",
            joint_mode and cw <= lo, model.min_tick)  # fmt: skip
        add("ccw_angle_limit", ccw, f"≥ {hi} (joint range {lo}…{hi}{wheel})",
            joint_mode and ccw >= hi, model.max_tick)  # fmt: skip
    if "min_position_limit" in table:  # Protocol 2.0 (XM, …)
        low = _read(bus, sid, table, "min_position_limit", signed=False)
        high = _read(bus, sid, table, "max_position_limit", signed=False)
        add("min_position_limit", low, f"≤ {lo} (joint range {lo}…{hi})", low <= lo,
            model.min_tick)  # fmt: skip
        add("max_position_limit", high, f"≥ {hi} (joint range {lo}…{hi})", high >= hi,
            model.max_tick)  # fmt: skip
    if "homing_offset" in table:
        offset = _read(bus, sid, table, "homing_offset", signed=True)
        add("homing_offset", offset, "0", offset == 0, 0)
    if "drive_mode" in table:
        drive = _read(bus, sid, table, "drive_mode", signed=False)
        add("drive_mode", drive, "reverse bit 0 clear", not drive & _REVERSE_BIT,
            drive & ~_REVERSE_BIT)  # fmt: skip
    return out


def locked(bus: DynamixelBus, joint: JointConfig, table: ControlTable) -> bool:
    """Protocol 1.0: the Lock register is set (EEPROM read-only until the servo is powered off)."""
    return "lock" in table and _read(bus, joint.servo_id, table, "lock", signed=False) == 1


def fix_servo(
    bus: DynamixelBus, joint: JointConfig, table: ControlTable, findings: list[RegisterFinding]
) -> list[RegisterFinding]:
    """Write the expected values of ``findings`` (torque off first: EEPROM), then read the
    registers back; returns what still mismatches. A locked Protocol 1.0 EEPROM is refused."""
    sid = joint.servo_id
    if locked(bus, joint, table):
        raise HardwareError(
            f"servo ID {sid} (joint {joint.name}) on bus {bus.name}: its EEPROM is locked "
            "(Lock = 1) until it is powered off; power-cycle the robot and run again to fix its "
            "registers"
        )
    writes = [("torque_enable", 0)] + [(f.register, f.fix) for f in findings if f.fix is not None]
    for name, value in writes:
        reg = table[name]
        err = bus.write(sid, reg.address, p.le_bytes(value, reg.size))
        if err & (0x7F if bus.protocol == 2.0 else 0xFF):
            raise HardwareError(
                f"servo ID {sid} (joint {joint.name}) refused {name} = {value} (error "
                f"0x{err:02x}); check the value range in its e-Manual"
            )
    return [f for f in check_servo(bus, joint, table) if not f.ok]
