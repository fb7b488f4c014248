"""Servo EEPROM that other tools may have left behind, checked against the robot config.

A servo keeps its EEPROM across tools. Four kinds of leftovers silently change what a goal
position means or whether it is obeyed:

- **angle / position limits** (Protocol 1.0 CW/CCW Angle Limit, Protocol 2.0 Min/Max Position
  Limit): a goal outside them is refused by the servo — silently under Sync Write. pypot writes
  its JSON ``angle_limit`` into them raw (servo frame, no orientation or offset); on a Poppy
  that has run pypot 13 of 25 joints would refuse part of their configured range by more than
  a tick (9 more by one tick of pypot's 4095-step rounding). Both limits 0 on Protocol 1.0 is
  wheel mode, both 4095 on an MX multi-turn mode.
- **Homing Offset** (Protocol 2.0): added by the servo to Present Position (and so to where a
  goal lands); LeRobot's calibration writes it.
- **Drive Mode bit 0, reverse** (Protocol 2.0): mirrors the direction of rotation; LeRobot's
  calibration writes it too. The config's ``direction`` already handles a joint's sign.
- **Status Return Level** (both protocols): below 2 a servo answers reads but not writes, so
  every write this project waits a reply for times out (the stream's connect fails after
  retries, blaming power and cabling). Expected: 2, a reply to every instruction.

What this project expects: limits that contain every tick the config's joint range can command
(the config's limits through its direction and zero offset, robot.servo_units; the fix writes
the model's full range, as ROBOTIS' own OP3 framework does), Homing Offset 0, the reverse bit
0. :func:`check_servo` reads the registers and reports each as a :class:`RegisterFinding`; the
backend refuses to connect on any mismatch unless told to fix (:func:`fix_servo`: torque off,
EEPROM written, read back). A Protocol 1.0 servo with Lock = 1 keeps its EEPROM read-only until
it is powered off: it is not written, :class:`EepromLockedError` says so.
"""

from __future__ import annotations

from dataclasses import dataclass

from robot_retarget.errors import HardwareError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.control_table import ControlTable
from robot_retarget.robot.config import JointConfig
from robot_retarget.robot.servo_units import JointServoUnits

REVERSE_BIT = 0x01  # Drive Mode bit 0 (XM430 e-Manual): 1 = reverse mode
STATUS_TO_ALL = 2  # Status Return Level: a status packet for every instruction (the default)


def fix_advice(robot: str = "R", port: str | None = None) -> str:
    """What to tell the user whenever registers disagree with the config, with the robot and
    the bus's ``--port`` item filled in where known."""
    args = f"--robot {robot}" + ("" if port is None else f" --port {port}")
    return (
        f"Run `robot-retarget doctor {args}` to see every servo's registers, then `doctor "
        f"{args} --fix-registers` (or `stream --fix-registers`, DynamixelBackend(..., "
        "fix_registers=True)) to write the expected values with the torque off"
    )


FIX_ADVICE = fix_advice()  # the robot and port not known


@dataclass(frozen=True)
class RegisterFinding:
    """One register of one servo: the value found, the values the config accepts
    (``expected_range``, inclusive; described by ``expected``) and what a fix writes."""

    servo_id: int
    joint: str
    register: str
    found: int
    expected: str
    expected_range: tuple[int, int]
    ok: bool
    fix: int | None  # value to write, None when nothing is to be written


def servo_summary(findings: list[RegisterFinding]) -> str:
    """One line per servo for ``doctor``: OK with the values, or each mismatch with found and
    expected values (``findings`` of one servo, as :func:`check_servo` returns them)."""
    first = findings[0]
    bad = [f for f in findings if not f.ok]
    values = ", ".join(f"{f.register} {f.found}" for f in findings)
    head = f"ID {first.servo_id} ({first.joint}):"
    if not bad:
        return f"{head} OK ({values})"
    wrong = "; ".join(f"{f.register} = {f.found}, expected {f.expected}" for f in bad)
    return f"{head} MISMATCH {wrong}"


class RegisterMismatchError(HardwareError):
    """A servo's EEPROM disagrees with the config. Attributes name the servo (``servo_id``,
    ``joint``), the ``register``, the value ``found``, the accepted ``expected_range``
    (inclusive) and its description ``expected``, and the ``bus``; ``findings`` holds every
    mismatch found. ``after_fix``: the values were written and did not read back."""

    def __init__(
        self,
        findings: list[RegisterFinding],
        bus: str,
        *,
        after_fix: bool = False,
        robot: str | None = None,
        port: str | None = None,
    ) -> None:
        first = findings[0]
        self.servo_id = first.servo_id
        self.joint = first.joint
        self.register = first.register
        self.found = first.found
        self.expected = first.expected
        self.expected_range = first.expected_range
        self.bus = bus
        self.findings = findings
        self.after_fix = after_fix
        more = f" (and {len(findings) - 1} more)" if len(findings) > 1 else ""
        what = (
            f"servo ID {first.servo_id} (joint {first.joint}) on bus {bus}: {first.register} = "
            f"{first.found}, expected {first.expected}{more}"
        )
        if after_fix:
            super().__init__(
                f"{what} after writing the expected values: the servo did not keep them. "
                "Nothing was moved; check its firmware version and e-Manual, or set the "
                "register with ROBOTIS' Dynamixel Wizard"
            )
        else:
            advice = FIX_ADVICE if robot is None else fix_advice(robot, port)
            super().__init__(f"{what}. Another tool left it there; nothing was moved. {advice}")


class EepromLockedError(HardwareError):
    """Protocol 1.0: the servo's Lock register is 1, so its EEPROM cannot be written until it is
    powered off. ``register`` is "lock", ``found`` 1, ``expected_range`` (0, 0); ``findings``
    are the mismatches that could not be fixed."""

    def __init__(
        self, servo_id: int, joint: str, bus: str, findings: list[RegisterFinding]
    ) -> None:
        self.servo_id = servo_id
        self.joint = joint
        self.bus = bus
        self.register = "lock"
        self.found = 1
        self.expected_range = (0, 0)
        self.findings = findings
        names = ", ".join(f.register for f in findings) or "its registers"
        super().__init__(
            f"servo ID {servo_id} (joint {joint}) on bus {bus}: its EEPROM is locked (lock = 1) "
            f"until it is powered off, so {names} cannot be fixed; power-cycle the robot and run "
            "`doctor --fix-registers` again"
        )


class RegisterWriteError(HardwareError):
    """A servo answered a register write with an error: ``servo_id``, ``joint``, ``register``,
    ``value`` written and the status ``error`` byte."""

    def __init__(self, servo_id: int, joint: str, register: str, value: int, error: int) -> None:
        self.servo_id = servo_id
        self.joint = joint
        self.register = register
        self.value = value
        self.error = error
        super().__init__(
            f"servo ID {servo_id} (joint {joint}) refused {register} = {value} (error "
            f"0x{error:02x}); check the value range in its e-Manual"
        )


def read_registers(
    bus: DynamixelBus, sid: int, table: ControlTable, names: list[str]
) -> dict[str, int]:
    """Values of registers ``names`` of servo ``sid``, read in one transaction."""
    regs = [table[n] for n in names]
    start = min(r.address for r in regs)
    length = max(r.address + r.size for r in regs) - start
    _err, data = bus.read(sid, start, length)
    if len(data) != length:
        raise HardwareError(
            f"servo ID {sid} answered a read of {length} bytes at {start} with {len(data)} "
            f"bytes; check that it is a {table.model}"
        )
    return {
        r.name: p.from_le(data[r.address - start : r.address - start + r.size], r.signed)
        for r in regs
    }


def joint_tick_range(joint: JointConfig) -> tuple[int, int]:
    """The lowest and highest tick the config's joint range commands (direction and zero offset
    applied: a reversed joint's lower limit is its servo's higher tick; rounded inward)."""
    return JointServoUnits(joint).limit_ticks()


def check_servo(
    bus: DynamixelBus, joint: JointConfig, table: ControlTable
) -> list[RegisterFinding]:
    """Read and judge the limit, homing and drive-mode registers of ``joint``'s servo."""
    sid = joint.servo_id
    lo, hi = joint_tick_range(joint)
    model = JointServoUnits(joint).model
    out: list[RegisterFinding] = []

    def add(register: str, found: int, expected: str, allowed: tuple[int, int], ok: bool,
            fix: int) -> None:  # fmt: skip
        out.append(
            RegisterFinding(
                sid, joint.name, register, found, expected, allowed, ok, None if ok else fix
            )
        )

    span = f"joint range {lo}…{hi}"
    if "cw_angle_limit" in table:  # Protocol 1.0 (AX, MX)
        v = read_registers(bus, sid, table, ["cw_angle_limit", "ccw_angle_limit"])
        cw, ccw = v["cw_angle_limit"], v["ccw_angle_limit"]
        wheel = cw == 0 and ccw == 0  # no position control at all
        multi = "multi_turn_offset" in table and cw == ccw == model.max_tick  # MX multi-turn
        mode = (
            ", not wheel mode (CW = CCW = 0)"
            if wheel
            else ", not multi-turn mode (CW = CCW = 4095)"
            if multi
            else ""
        )
        joint_mode = not (wheel or multi)
        add("cw_angle_limit", cw, f"≤ {lo} ({span}{mode})", (model.min_tick, lo),
            joint_mode and cw <= lo, model.min_tick)  # fmt: skip
        add("ccw_angle_limit", ccw, f"≥ {hi} ({span}{mode})", (hi, model.max_tick),
            joint_mode and ccw >= hi, model.max_tick)  # fmt: skip
    if "min_position_limit" in table:  # Protocol 2.0 (XM, …)
        names = ["drive_mode", "homing_offset", "max_position_limit", "min_position_limit"]
        v = read_registers(bus, sid, table, names)
        low, high = v["min_position_limit"], v["max_position_limit"]
        add("min_position_limit", low, f"≤ {lo} ({span})", (model.min_tick, lo), low <= lo,
            model.min_tick)  # fmt: skip
        add("max_position_limit", high, f"≥ {hi} ({span})", (hi, model.max_tick), high >= hi,
            model.max_tick)  # fmt: skip
        offset = v["homing_offset"]
        add("homing_offset", offset, "0", (0, 0), offset == 0, 0)
        drive = v["drive_mode"]
        cleared = drive & ~REVERSE_BIT  # the other bits (profile, torque-on-by-goal) stay
        add("drive_mode", drive, f"{cleared} (reverse bit 0 clear)", (cleared, cleared),
            not drive & REVERSE_BIT, cleared)  # fmt: skip
    level = read_registers(bus, sid, table, ["status_return_level"])["status_return_level"]
    add("status_return_level", level, f"{STATUS_TO_ALL} (a reply to every instruction)",
        (STATUS_TO_ALL, STATUS_TO_ALL), level == STATUS_TO_ALL, STATUS_TO_ALL)  # fmt: skip
    return out


def locked(bus: DynamixelBus, joint: JointConfig, table: ControlTable) -> bool:
    """Protocol 1.0: the Lock register is set (EEPROM read-only until the servo is powered off)."""
    if "lock" not in table:
        return False
    return read_registers(bus, joint.servo_id, table, ["lock"])["lock"] == 1


def fix_servo(
    bus: DynamixelBus, joint: JointConfig, table: ControlTable, findings: list[RegisterFinding]
) -> list[RegisterFinding]:
    """Write the expected values of ``findings`` (torque off first: EEPROM), then read the
    registers back; returns what still mismatches. A locked Protocol 1.0 EEPROM raises
    :class:`EepromLockedError` before anything is written."""
    sid = joint.servo_id
    todo = [f for f in findings if f.fix is not None]
    if not todo:
        return [f for f in findings if not f.ok]
    if locked(bus, joint, table):
        raise EepromLockedError(sid, joint.name, bus.name, todo)
    # Status bits that mean "refused": Protocol 2.0 the error number (the alert bit 0x80 only
    # says Hardware Error Status is set); Protocol 1.0 instruction, checksum, range and angle
    # limit errors (voltage, overheating and overload bits report the servo, not the write).
    refused = 0x7F if bus.protocol == 2.0 else 0x5A
    level = next((f for f in todo if f.register == "status_return_level"), None)
    if level is not None and level.fix is not None:
        # First, and with no reply awaited: at a lower level the servo answers no write.
        reg = table["status_return_level"]
        bus.write_no_reply(sid, reg.address, p.le_bytes(level.fix, reg.size))
        todo = [f for f in todo if f is not level]
    writes = [("torque_enable", 0)] + [(f.register, f.fix) for f in todo if f.fix is not None]
    for name, value in writes:
        reg = table[name]
        err = bus.write(sid, reg.address, p.le_bytes(value, reg.size))
        if err & refused:
            raise RegisterWriteError(sid, joint.name, name, value, err)
    return [f for f in check_servo(bus, joint, table) if not f.ok]
