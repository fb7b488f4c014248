"""JointBackend for Dynamixel servos on one or more serial buses (dynamixel-sdk + pyserial).

Per bus, each cycle is one Sync Write of goal positions and one read of the present-state block:
Protocol 2.0 Sync Read (Fast Sync Read where every servo on the bus supports it); Protocol 1.0
Bulk Read for MX servos and per-servo reads for the rest (AX-12A has no Bulk Read).

Safety rules kept here (the SafetyLayer in front does the limit clamping):
- connect(): ping every configured ID and compare the model number; check the EEPROM other
  tools leave behind (angle/position limits, Homing Offset, Drive Mode: refuse on a mismatch,
  or write the expected values with ``fix_registers``; robot_retarget.hardware.servo_registers);
  set return delay time, operating mode and profile velocity/acceleration; torque stays off.
- Torque goes on only at the first send(): goal := present position, torque on, then a
  velocity-limited ramp to the first command. Never a jump.
- Torque off on disconnect(), on any exception inside send()/read_state(), and on SIGINT /
  SIGTERM (handlers installed while connected, in the main thread only).
- A servo hardware error (overload, overheating, input voltage, encoder, electrical shock)
  raises ServoFaultError naming servo and bits; torque goes off and the stream stops.
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass
from types import FrameType
from typing import Any

import numpy as np

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.errors import CommunicationError, HardwareError, ServoFaultError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.hardware.bus import ByteArray, DynamixelBus, ReadResult, as_block
from robot_retarget.hardware.control_table import (
    ControlTable,
    control_table,
    error_bit_names,
)
from robot_retarget.hardware.goal_packet import GoalPacket
from robot_retarget.hardware.safety import CLOCK_BUDGET_PERIODS, UnsafeCommandError
from robot_retarget.hardware.servo_registers import (
    RegisterFinding,
    RegisterMismatchError,
    check_servo,
    fix_servo,
)
from robot_retarget.hardware.stage_timer import StageTimer
from robot_retarget.hardware.state_block import StateBlock
from robot_retarget.hardware.types import JointCommand, JointState
from robot_retarget.hardware.velocity_budget import VelocityBudget
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.servo_models import servo_model
from robot_retarget.robot.servo_units import ServoUnits

_RPM2_PER_LSB = 214.577  # XM430 Profile Acceleration unit, rev/min²
_MX_ACCEL_DEG_S2_PER_LSB = 8.583  # MX Goal Acceleration unit
_POSITION_CONTROL_MODE = 3
# Read every tick. Protocol 2.0: Present Load … Present Position (10 bytes; the span to Present
# Temperature would be 21 bytes per servo, +1.1 ms on OP3's 2 Mbps wire). Protocol 1.0: the
# span already ends at Present Temperature (8 bytes).
_STATE_REGISTERS_V2 = ("present_load", "present_velocity", "present_position")
_STATE_REGISTERS_V1 = ("present_position", "present_speed", "present_load", "present_temperature")
# Temperature changes over seconds: on Protocol 2.0 it is read on its own about once a second.
_TEMPERATURE_PERIOD_S = 1.0


class ModelMismatchError(HardwareError):
    """A servo answered with another model number than the config expects."""

    def __init__(self, message: str, *, servo_id: int, expected: int, found: int) -> None:
        self.servo_id = servo_id
        self.expected = expected
        self.found = found
        super().__init__(message)


class NotConnectedError(HardwareError):
    """The backend is used before connect() or after disconnect() / a fault."""


# Rounding slack for the joint-limit check: commands come from float64 math on the limits.
_LIMIT_TOL_RAD = 1e-9
# The backend's clock budget saves up this many control periods of each joint's velocity limit:
# twice the SafetyLayer's, so behind one it never refuses a step (the slack covers the time
# between the layer's clamp and the backend's write).
BACKEND_BUDGET_PERIODS = 2.0 * CLOCK_BUDGET_PERIODS
_REST_TOL_RAD = 0.02
"""A joint found this far past a limit before torque on (1.1°: a few ticks of sag onto a
stop) is held at the limit; farther is refused (the config or the robot is wrong)."""


@dataclass
class _BusGroup:
    """The joints of one bus, and how to write and read them (packets laid out once)."""

    name: str
    bus: DynamixelBus
    joint_index: list[int]  # into config.joints
    ids: list[int]
    tables: list[ControlTable]
    fast: bool  # Protocol 2.0: Fast Sync Read
    bulk_ids: list[int]  # Protocol 1.0: read by Bulk Read
    single_ids: list[int]  # Protocol 1.0: read one by one
    goal: GoalPacket
    state: StateBlock  # read every tick
    temperature: StateBlock | None  # Protocol 2.0: read about once a second
    joints: IntArray  # joint_index as an array
    direction: FloatArray  # per servo of the group
    velocity_unit_rad_s: FloatArray
    full_load: FloatArray
    read_packet: bytes = b""  # Protocol 2.0 (Fast) Sync Read request, built at connect
    temperature_packet: bytes = b""


_BusRead = tuple[ByteArray, ByteArray, tuple[ByteArray, ByteArray] | None]


class DynamixelBackend(JointBackend):
    """Dynamixel robot on ``buses`` (bus name in the config → DynamixelBus, opened here).

    ``fix_registers``: where a servo's angle/position limits, Homing Offset or Drive Mode
    disagree with the config, connect() writes the expected values (torque off) and reads them
    back instead of raising RegisterMismatchError; a locked Protocol 1.0 EEPROM still raises
    (EepromLockedError).

    ``parallel_buses``: with several buses, each tick's state reads run at the same time, one
    thread per extra bus (a read is mostly waiting for the servos' bytes on the wire, and the
    serial driver releases the GIL while it waits), so a tick costs the slowest bus, not their
    sum. Goal writes stay sequential (the driver queues them without waiting); fault checks and
    decoding run after every bus is idle again, in bus order.
    """

    def __init__(
        self,
        config: RobotConfig,
        buses: Mapping[str, DynamixelBus],
        *,
        fast_sync_read: bool = True,
        ramp_speed_fraction: float = 0.25,
        handle_signals: bool = True,
        sleep: Callable[[float], None] = time.sleep,
        fix_registers: bool = False,
        parallel_buses: bool = True,
    ) -> None:
        missing = [b.name for b in config.buses if b.name not in buses]
        if missing:
            raise HardwareError(
                f"robot {config.name}: no DynamixelBus given for bus(es) {missing}; "
                f"pass one per config bus: {[b.name for b in config.buses]}"
            )
        if not 0.0 < ramp_speed_fraction <= 1.0:
            raise ValueError(f"ramp_speed_fraction must be in (0, 1], got {ramp_speed_fraction}")
        self.fix_registers = fix_registers
        self.config = config
        self.units = ServoUnits(config)
        self._lower = config.lower
        self._upper = config.upper
        self.ramp_speed_fraction = ramp_speed_fraction
        self.handle_signals = handle_signals
        self._sleep = sleep
        self._groups: list[_BusGroup] = []
        for bc in config.buses:
            idx = [i for i, j in enumerate(config.joints) if j.bus == bc.name]
            if not idx:
                continue
            tables = [control_table(config.joints[i].servo_model) for i in idx]
            ids = [config.joints[i].servo_id for i in idx]
            v2 = float(bc.protocol) == 2.0
            state = StateBlock(tables[0], _STATE_REGISTERS_V2 if v2 else _STATE_REGISTERS_V1)
            goal_reg = tables[0]["goal_position"]
            goal_at = (goal_reg.address, goal_reg.size)
            odd = [
                t.model
                for t in tables
                if not state.matches(t)
                or (t["goal_position"].address, t["goal_position"].size) != goal_at
            ]
            if odd:
                raise HardwareError(
                    f"bus {bc.name}: servo models {sorted(set(odd))} keep goal or present state "
                    f"elsewhere than {tables[0].model}; one Sync Write / Read cannot serve them: "
                    "put them on their own bus in the config"
                )
            self._groups.append(
                _BusGroup(
                    name=bc.name,
                    bus=buses[bc.name],
                    joint_index=idx,
                    ids=ids,
                    tables=tables,
                    fast=v2 and fast_sync_read and all(t.fast_sync_read for t in tables),
                    bulk_ids=[]
                    if v2
                    else [i for i, t in zip(ids, tables, strict=True) if t.bulk_read],
                    single_ids=[]
                    if v2
                    else [i for i, t in zip(ids, tables, strict=True) if not t.bulk_read],
                    goal=GoalPacket(bc.protocol, goal_reg.address, goal_reg.size, ids),
                    state=state,
                    temperature=StateBlock(tables[0], ("present_temperature",)) if v2 else None,
                    joints=np.asarray(idx, dtype=np.intp),
                    direction=np.array([config.joints[i].direction for i in idx], dtype=float),
                    velocity_unit_rad_s=np.array([t.velocity_unit_rad_s for t in tables]),
                    full_load=np.array([t.full_load for t in tables], dtype=float),
                )
            )
        n = config.num_joints
        # Last read per joint: Hardware Error Status (P2.0) / status error bits (P1.0).
        self.hardware_error: IntArray = np.zeros(n, dtype=np.int64)
        self._temperature: FloatArray = np.full(n, np.nan)
        self._temperature_every = max(1, round(_TEMPERATURE_PERIOD_S * config.control_rate_hz))
        self._reads = 0
        # Optional: per-stage durations of send / read_state (bench loop sets one).
        self.stage_timer: StageTimer | None = None
        self._connected = False
        self._torque_on = False
        self._faulted: HardwareError | None = None
        self._last_q: FloatArray | None = None
        self._command_period_s = 1.0 / config.control_rate_hz  # set_command_period
        # Its own clock budget, as the SafetyLayer's but twice as deep: a backend used without
        # one is refused commands that move faster than the time between them allows.
        self._budget = VelocityBudget(  # set_command_period, set_command_clock
            config.max_velocity, BACKEND_BUDGET_PERIODS * self._command_period_s, time.monotonic
        )
        self._old_handlers: dict[int, Any] = {}
        self.last_packets: dict[str, bytes] = {}  # bus name → last goal Sync Write sent
        self.parallel_buses = parallel_buses  # may be switched between ticks (bench loop)
        self._pool: ThreadPoolExecutor | None = None

    # ----- per bus -----------------------------------------------------------------------------
    def _group(self, bus_name: str) -> _BusGroup:
        for g in self._groups:
            if g.name == bus_name:
                return g
        raise KeyError(f"robot {self.config.name} has no bus {bus_name!r}")

    def bus(self, bus_name: str) -> DynamixelBus:
        """The DynamixelBus of config bus ``bus_name``."""
        return self._group(bus_name).bus

    def state_block(self, bus_name: str) -> StateBlock:
        """The registers read from every servo of ``bus_name`` each tick."""
        return self._group(bus_name).state

    def uses_fast_sync_read(self, bus_name: str) -> bool:
        """Whether ``bus_name`` is read by Fast Sync Read (known after connect: firmware)."""
        return self._group(bus_name).fast

    # ----- lifecycle -------------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self._connected

    @property
    def torque_on(self) -> bool:
        return self._torque_on

    def connect(self) -> None:
        try:
            for g in self._groups:
                if not g.bus.is_open:
                    g.bus.open()
            self._check_models()
            self._build_read_packets()
            self._check_registers()
            self._configure_servos()
            state = self._read_state_raw()
        except BaseException:
            self._close_buses()
            raise
        self._last_q = state.q.copy()
        self._budget.fill()
        self._connected = True
        self._faulted = None
        self._install_signal_handlers()

    def disconnect(self) -> None:
        try:
            if self._connected and self._torque_on and self.config.hardware.torque_off_at_safe_pose:
                # The torque goes off below whatever happens on the way to the safe pose.
                with contextlib.suppress(HardwareError):
                    self._ramp_to(self.config.safe_pose)
            self.torque_off()
        finally:
            self._connected = False
            self._restore_signal_handlers()
            self._close_buses()

    def _close_buses(self) -> None:
        self._stop_workers()
        for g in self._groups:
            g.bus.close()

    def _stop_workers(self) -> None:
        """Wait for in-flight bus reads, then end the worker threads."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    # ----- connect-time checks -----------------------------------------------------------------
    def _check_models(self) -> None:
        for g in self._groups:
            for i in g.joint_index:
                joint = self.config.joints[i]
                expected = servo_model(joint.servo_model).model_number
                try:
                    found, firmware = g.bus.ping_info(joint.servo_id)
                except CommunicationError as exc:
                    raise CommunicationError(
                        f"servo ID {joint.servo_id} (joint {joint.name}) on bus {g.name} "
                        f"({g.bus.port_name}) did not answer a ping: check its power, cable, ID "
                        f"and baud rate ({g.bus.baud_rate}); {exc}"
                    ) from exc
                if found != expected:
                    raise ModelMismatchError(
                        f"servo ID {joint.servo_id} (joint {joint.name}) on bus {g.name} is "
                        f"model number {found}, the config expects {expected} "
                        f"({joint.servo_model}); fix the config or the servo ID",
                        servo_id=joint.servo_id,
                        expected=expected,
                        found=found,
                    )
                table = control_table(joint.servo_model)
                if g.fast and firmware < table.fast_sync_read_min_firmware:
                    g.fast = False  # older firmware: plain Sync Read on this bus

    def _build_read_packets(self) -> None:
        for g in self._groups:
            if g.bus.protocol != 2.0:
                continue
            block = g.state
            g.read_packet = g.bus.sync_read_packet(block.address, block.size, g.ids, fast=g.fast)
            if g.temperature is not None:
                t = g.temperature
                g.temperature_packet = g.bus.sync_read_packet(t.address, t.size, g.ids, fast=g.fast)

    def _check_registers(self) -> None:
        """Limits, Homing Offset and Drive Mode as the config expects, or refuse (or, with
        ``fix_registers``, write them, with the torque off, and read them back)."""
        for g in self._groups:
            mismatches: list[RegisterFinding] = []
            for i, table in zip(g.joint_index, g.tables, strict=True):
                joint = self.config.joints[i]
                bad = [f for f in check_servo(g.bus, joint, table) if not f.ok]
                if bad and self.fix_registers:
                    bad = fix_servo(g.bus, joint, table, bad)  # read back: what did not stick
                mismatches += bad
            if mismatches:
                # The --port item that names this bus: BUS=PATH where the robot has several.
                port = g.bus.port_name
                if len(self.config.buses) > 1:
                    port = f"{g.name}={port}"
                raise RegisterMismatchError(
                    mismatches,
                    g.name,
                    after_fix=self.fix_registers,
                    robot=self.config.name,
                    port=port,
                )

    def _write_checked(
        self, g: _BusGroup, sid: int, table: ControlTable, name: str, value: int
    ) -> None:
        reg = table[name]
        err = g.bus.write(sid, reg.address, p.le_bytes(value, reg.size))
        if g.bus.protocol == 2.0:
            if err & 0x80:
                self._raise_fault(g, sid, self._hardware_error_bits(g, sid, table))
            bad = err & 0x7F
        else:
            if err & 0x25:
                self._raise_fault(g, sid, err & 0x25)
            bad = err & ~0x25
        if bad:
            raise HardwareError(
                f"servo ID {sid} on bus {g.name} refused {name} = {value} (error 0x{err:02x}); "
                "check the value range in the servo's e-Manual"
            )

    def _configure_servos(self) -> None:
        hw = self.config.hardware
        delay_units = min(254, round(hw.return_delay_us / 2.0))  # 2 µs per LSB
        n = self.config.num_joints
        speeds = (  # 0 = no profile limit on every model
            np.zeros(n, dtype=np.int64)
            if hw.profile_velocity_rad_s is None
            else self.units.velocity_to_steps(np.full(n, hw.profile_velocity_rad_s))
        )
        for g in self._groups:
            for sid, i, table in zip(g.ids, g.joint_index, g.tables, strict=True):
                self._write_checked(g, sid, table, "torque_enable", 0)  # EEPROM needs torque off
                self._write_checked(g, sid, table, "return_delay_time", delay_units)
                if "operating_mode" in table:
                    self._write_checked(g, sid, table, "operating_mode", _POSITION_CONTROL_MODE)
                speed = int(speeds[i])
                if "profile_velocity" in table:
                    self._write_checked(g, sid, table, "profile_velocity", speed)
                    accel = 0
                    if hw.profile_acceleration_rad_s2 is not None:
                        rev_min2 = hw.profile_acceleration_rad_s2 / (2 * math.pi) * 3600.0
                        accel = max(1, math.ceil(rev_min2 / _RPM2_PER_LSB))
                    self._write_checked(g, sid, table, "profile_acceleration", accel)
                else:
                    self._write_checked(g, sid, table, "moving_speed", speed)
                    if "goal_acceleration" in table and hw.profile_acceleration_rad_s2:
                        deg = math.degrees(hw.profile_acceleration_rad_s2)
                        accel = min(254, max(1, math.ceil(deg / _MX_ACCEL_DEG_S2_PER_LSB)))
                        self._write_checked(g, sid, table, "goal_acceleration", accel)

    # ----- torque ------------------------------------------------------------------------------
    def _sync_write_register(self, g: _BusGroup, name: str, values: Mapping[int, int]) -> bytes:
        reg = g.tables[0][name]
        return g.bus.sync_write(
            reg.address, reg.size, {sid: p.le_bytes(v, reg.size) for sid, v in values.items()}
        )

    def torque_off(self) -> None:
        """Best effort on every bus: a dead bus must not stop the others from switching off."""
        for g in self._groups:
            if not g.bus.is_open:
                continue
            for _ in range(2):  # Sync Write has no reply: send it twice
                try:
                    self._sync_write_register(g, "torque_enable", dict.fromkeys(g.ids, 0))
                except HardwareError:
                    break
        self._torque_on = False

    def _enable_torque_at_present(self) -> None:
        state = self._read_state_raw()
        lower, upper = self._lower - _REST_TOL_RAD, self._upper + _REST_TOL_RAD
        outside = (state.q < lower) | (state.q > upper)
        if np.any(outside):
            # Torque on would hold the joint there (goal := present), past its limit, and the
            # ramp would start from it: nothing is written.
            joints = [j for j, bad in zip(self.config.joints, outside, strict=True) if bad]
            where = ", ".join(
                f"{j.name} at {q:.3f} rad (limits {j.lower_rad:.3f} … {j.upper_rad:.3f})"
                for j, q in zip(joints, state.q[outside], strict=True)
            )
            raise UnsafeCommandError(
                f"joint(s) outside their limits before torque on: {where}; torque is off: move "
                "them inside by hand (or check the config's limits, zero offset and direction "
                "for them) and start again",
                joints=tuple(j.name for j in joints),
            )
        # Goal := present, inside the limits: a joint resting a hair past one (a tick of
        # rounding, a limb sagging onto its stop) is held at the limit instead.
        u = self.units
        ticks = np.clip(u.to_ticks(state.q), u.limit_lo_tick, u.limit_hi_tick)
        for g in self._groups:
            self._write_goals(g, ticks)
            self._sync_write_register(g, "torque_enable", dict.fromkeys(g.ids, 1))
        self._torque_on = True
        self._last_q = self._rad_from_ticks(ticks)

    def _ramp_to(self, q_target: FloatArray) -> None:
        """Velocity-limited move from the last goal to ``q_target`` at the control rate."""
        if self._last_q is None:
            return
        speed = self.config.max_velocity * self.ramp_speed_fraction
        if self.config.hardware.profile_velocity_rad_s is not None:
            speed = np.minimum(speed, self.config.hardware.profile_velocity_rad_s)
        dt_s = 1.0 / self.config.control_rate_hz
        delta = np.asarray(q_target, dtype=np.float64) - self._last_q
        # Each step a tick under speed · dt: the rounding to ticks adds at most one.
        per_step = np.maximum(speed * dt_s - self.units.rad_per_tick, 0.25 * speed * dt_s)
        steps = max(1, math.ceil(float(np.max(np.abs(delta) / per_step))))
        start = self._last_q.copy()
        # Each step a period after the one before was sent: a ramp that fell behind (a busy
        # machine) goes on at its speed, it does not send the steps it is late for at once.
        sent_s: float | None = None
        for k in range(1, steps + 1):
            if sent_s is not None:
                wait_s = sent_s + dt_s - time.monotonic()
                if wait_s > 0.0:
                    self._sleep(wait_s)
            q = start + delta * (k / steps)
            sent_s = time.monotonic()
            self._send_now(q, self._ticks_from_rad(q))
        self._budget.fill()  # the ramp went at its own pace: the stream starts afresh

    # ----- streaming ---------------------------------------------------------------------------
    def _require_ready(self) -> None:
        if self._faulted is not None:
            raise NotConnectedError(
                f"robot {self.config.name} stopped after a fault ({self._faulted}); fix it and "
                "connect again"
            )
        if not self._connected:
            raise NotConnectedError(f"robot {self.config.name}: connect() first")

    def _write_goals(self, g: _BusGroup, ticks: IntArray) -> None:
        timer = self.stage_timer
        packet = g.goal.build(ticks[g.joints])
        if timer is not None:
            timer.lap("packet_build")
        g.bus.write_packet(packet)
        self.last_packets[g.name] = packet
        if timer is not None:
            timer.lap("sdk_write")

    def _send_now(self, q: FloatArray, ticks: IntArray | None = None) -> FloatArray:
        if ticks is None:
            ticks = self.units.to_ticks(q)
        # The bookkeeping before the writes, so that a read_state() right after goes out with
        # the least idle time on the bus between the goal packet and its request.
        sent = self._rad_from_ticks(ticks)
        last_q = np.asarray(q, dtype=np.float64).copy()
        for g in self._groups:
            self._write_goals(g, ticks)
        self._last_q = last_q
        return sent

    @property
    def position_quantum_rad(self) -> FloatArray:
        """One position tick of each joint's servo: goals are rounded to it."""
        return self.units.rad_per_tick

    def rounded(self, q: FloatArray) -> FloatArray:
        return self._rad_from_ticks(self._ticks_from_rad(q))

    def set_command_period(self, period_s: float) -> None:
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"period_s must be a positive number of seconds, got {period_s}")
        self._command_period_s = period_s
        self._budget.resize(BACKEND_BUDGET_PERIODS * period_s)

    def set_command_clock(self, clock: Callable[[], float]) -> None:
        self._budget.clock = clock
        self._budget.fill()

    def _ticks_from_rad(self, q: FloatArray) -> IntArray:
        """ServoUnits.to_ticks for one finite (J,) vector, without its generic argument checks;
        a joint its servo cannot reach still raises there (ServoRangeError)."""
        u = self.units
        ticks = np.rint((q * u.direction + u.zero_offset_rad) / u.rad_per_tick) + u.zero_tick
        if ticks.min() < 0 or np.any(ticks > u.max_tick):
            return u.to_ticks(q)  # raises ServoRangeError naming the joint
        # A command at a limit rounds to the nearest tick, which may lie a hair past it: the
        # ticks inside the limits are the servo's whole range here.
        return np.minimum(np.maximum(ticks, u.limit_lo_tick), u.limit_hi_tick).astype(np.int64)

    def _rad_from_ticks(self, ticks: IntArray) -> FloatArray:
        """ServoUnits.from_ticks for one (J,) int64 vector, without its generic argument checks
        (a quarter of its cost per tick); a tick outside the model's range still raises there."""
        u = self.units
        if ticks.min() < 0 or np.any(ticks > u.max_tick):
            return u.from_ticks(ticks)  # raises ServoRangeError naming the joint
        return ((ticks - u.zero_tick) * u.rad_per_tick - u.zero_offset_rad) * u.direction

    def _check_joint_limits(self, q: FloatArray) -> None:
        """Defence in depth: the SafetyLayer in front clamps to the limits, but a backend used on
        its own must not drive a joint into its mechanical stop either. Refused, not clamped
        (clamping here would hide an upstream bug); send() then switches torque off, as for every
        exception."""
        outside = (q < self._lower - _LIMIT_TOL_RAD) | (q > self._upper + _LIMIT_TOL_RAD)
        if not np.any(outside):
            return
        names = tuple(j.name for j, bad in zip(self.config.joints, outside, strict=True) if bad)
        raise UnsafeCommandError(
            f"command outside the joint limits of {', '.join(names)} "
            f"(q = {np.round(q[outside], 4).tolist()} rad); nothing was sent, torque is off. "
            "Put a SafetyLayer in front of the backend to clamp commands",
            joints=names,
        )

    def _check_step(self, q: FloatArray) -> None:
        """Defence in depth, as _check_joint_limits: no command moves a joint further than its
        velocity limit allows in one control period (the SafetyLayer in front bounds every step
        to that; a backend used on its own is refused a jump, not made to slew it), nor further
        than it allows in the time that really passed (the clock budget: commands sent faster
        than real time, whatever their stamps)."""
        if self._last_q is None:
            return
        step = np.abs(q - self._last_q)
        tick = self.units.rad_per_tick
        bound = self.config.max_velocity * self._command_period_s
        excess = step - bound - tick
        if np.any(excess > 0.0):
            bad = excess > 0.0
            names = tuple(j.name for j, b in zip(self.config.joints, bad, strict=True) if b)
            raise UnsafeCommandError(
                f"command moves {', '.join(names)} by {np.round(step[bad], 4).tolist()} rad in "
                "one command, more than the velocity limit allows in a command period "
                f"({np.round(bound[bad], 4).tolist()} rad); nothing was sent, torque is off (a "
                "SafetyLayer in front bounds every step: use one, and tell the backend the "
                "period it runs at with set_command_period)",
                joints=names,
            )
        budget = self._budget.available()
        if np.any(step > budget + tick):
            bad = step > budget + tick
            names = tuple(j.name for j, b in zip(self.config.joints, bad, strict=True) if b)
            raise UnsafeCommandError(
                f"commands come faster than real time: {', '.join(names)} would move "
                f"{np.round(step[bad], 4).tolist()} rad, but at the velocity limit only "
                f"{np.round(budget[bad], 4).tolist()} rad more fit in the time that passed; "
                "nothing was sent, torque is off (send each command at the time it is stamped "
                "with, or put a SafetyLayer in front, which bounds steps by the time that passed)",
                joints=names,
            )
        self._budget.spend(step)

    def send(self, cmd: JointCommand) -> JointCommand:
        self._require_ready()
        q = cmd.q
        if q.shape != (self.config.num_joints,):
            raise HardwareError(
                f"command has {q.shape} values, robot {self.config.name} has "
                f"{self.config.num_joints} joints"
            )
        if not np.all(np.isfinite(q)):
            raise HardwareError(f"command contains NaN/inf ({q}); nothing was sent")
        try:
            self._check_joint_limits(q)
            ticks = self._ticks_from_rad(q)  # range check before anything moves
            if self.stage_timer is not None:
                self.stage_timer.lap("limit_check")
            if not self._torque_on:
                self._enable_torque_at_present()
                self._ramp_to(q)
            else:
                self._check_step(q)
            sent = self._send_now(q, ticks)
        except BaseException as exc:
            self._stop_after(exc)
            raise
        return JointCommand(sent, cmd.t_s)

    def read_state(self) -> JointState:
        self._require_ready()
        try:
            return self._read_state_raw()
        except BaseException as exc:
            self._stop_after(exc)
            raise

    def _stop_after(self, exc: BaseException) -> None:
        self.torque_off()
        if isinstance(exc, HardwareError):
            self._faulted = exc

    # ----- reading -----------------------------------------------------------------------------
    def _raise_fault(self, g: _BusGroup, sid: int, bits: int) -> None:
        names = error_bit_names(bits, g.bus.protocol) or (f"0x{bits:02x}",)
        joint = self.config.joints[g.joint_index[g.ids.index(sid)]].name
        self.torque_off()
        err = ServoFaultError(
            f"servo ID {sid} (joint {joint}) on bus {g.name} reports a hardware error: "
            f"{', '.join(names)}; torque is off. Check load, temperature and supply, then reboot "
            "the servo (or power-cycle) before connecting again",
            servo_id=sid,
            bits=names,
        )
        self._faulted = err
        raise err

    def _hardware_error_bits(self, g: _BusGroup, sid: int, table: ControlTable) -> int:
        """Protocol 2.0: the alert bit says "look at Hardware Error Status": read it."""
        reg = table["hardware_error_status"]
        _, data = g.bus.read(sid, reg.address, reg.size)
        return data[0] if data else 0

    def _check_faults(self, g: _BusGroup, errors: ByteArray) -> None:
        """Fill ``hardware_error`` for every servo that reports one, then raise for the first."""
        v2 = g.bus.protocol == 2.0
        bad = np.flatnonzero(errors & (p.ERR2_ALERT if v2 else 0x25))
        if bad.size == 0:
            return
        first: tuple[int, int] | None = None
        for k in bad.tolist():
            sid = g.ids[k]
            bits = self._hardware_error_bits(g, sid, g.tables[k]) if v2 else int(errors[k]) & 0x25
            self.hardware_error[g.joint_index[k]] = bits
            if first is None:
                first = (sid, bits)
        if first is not None:
            self._raise_fault(g, *first)

    def _read_group(self, g: _BusGroup) -> tuple[ByteArray, ByteArray]:
        """(error byte per servo, (N, block) data) of the per-tick state block, in ID order."""
        block = g.state
        if g.bus.protocol == 2.0:
            return g.bus.sync_read_block(g.read_packet, g.ids, block.size, fast=g.fast)
        out: ReadResult = {}
        if g.bulk_ids:
            out.update(g.bus.bulk_read([(sid, block.address, block.size) for sid in g.bulk_ids]))
        for sid in g.single_ids:
            out[sid] = g.bus.read(sid, block.address, block.size)
        return as_block(out, g.ids, block.size)

    def _read_bus(self, g: _BusGroup, slow: bool) -> _BusRead:
        """One bus's bytes of this tick: the state block, and the temperatures when ``slow``.
        Bus I/O only (it may run in a worker thread): no checks, no shared state."""
        errors, data = self._read_group(g)
        t = g.temperature
        if not slow or t is None:
            return errors, data, None
        return errors, data, g.bus.sync_read_block(g.temperature_packet, g.ids, t.size, fast=g.fast)

    def _read_buses(self, slow: bool) -> list[_BusRead]:
        groups = self._groups
        if not self.parallel_buses or len(groups) < 2:
            return [self._read_bus(g, slow) for g in groups]
        if self._pool is None:  # made on the first read, ended when the buses close
            self._pool = ThreadPoolExecutor(
                len(groups) - 1, thread_name_prefix=f"{self.config.name}-bus"
            )
        others = [self._pool.submit(self._read_bus, g, slow) for g in groups[1:]]
        try:
            first = self._read_bus(groups[0], slow)
        finally:
            # Every bus is idle again before anything (a fault's torque-off) touches one.
            wait(others)
        return [first, *(f.result() for f in others)]

    def _read_state_raw(self) -> JointState:
        slow = self._reads % self._temperature_every == 0
        self._reads += 1
        reads = self._read_buses(slow)  # the request first, everything else after the reply
        timer = self.stage_timer
        if timer is not None:
            timer.lap("read")
        n = self.config.num_joints
        ticks = np.zeros(n, dtype=np.int64)
        vel = np.zeros(n)
        load = np.zeros(n)
        for g, (errors, data, temperatures) in zip(self._groups, reads, strict=True):
            if temperatures is not None and g.temperature is not None:
                self._check_faults(g, temperatures[0])
                self._temperature[g.joints] = g.temperature.decode(
                    temperatures[1], "present_temperature"
                )
            self._check_faults(g, errors)
            block, idx = g.state, g.joints
            rec = block.records(data)
            speed = "present_velocity" if "present_velocity" in block else "present_speed"
            ticks[idx] = block.value(rec, "present_position")
            vel[idx] = g.direction * block.value(rec, speed) * g.velocity_unit_rad_s
            load[idx] = g.direction * block.value(rec, "present_load") / g.full_load
            if "present_temperature" in block:
                self._temperature[idx] = block.value(rec, "present_temperature")
        state = JointState(
            q=self._rad_from_ticks(ticks),
            velocity=vel,
            load=load,
            temperature=self._temperature,
            hardware_error=self.hardware_error,
            t_s=time.monotonic(),
        )
        if timer is not None:
            timer.lap("decode")
        return state

    # ----- signals -----------------------------------------------------------------------------
    def _install_signal_handlers(self) -> None:
        if not self.handle_signals or threading.current_thread() is not threading.main_thread():
            return
        for signum in (signal.SIGINT, signal.SIGTERM):
            self._old_handlers[signum] = signal.signal(signum, self._on_signal)

    def _restore_signal_handlers(self) -> None:
        for signum, handler in self._old_handlers.items():
            signal.signal(signum, handler)
        self._old_handlers.clear()

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self._stop_workers()  # a read in flight on another bus ends first: torque-off owns them
        self.torque_off()
        self._connected = False
        self._restore_signal_handlers()
        self._close_buses()
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise SystemExit(128 + signum)
