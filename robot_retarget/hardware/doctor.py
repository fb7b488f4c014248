"""Checks behind ``robot-retarget doctor``: serial ports, FTDI latency timers, which servos
answer on a bus compared with the robot config, each servo's limit, Homing Offset and Drive
Mode registers (robot_retarget.hardware.servo_registers; fixed on request), and a measured
read/write cycle time.

No printing here: functions return small dataclasses the CLI formats.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from serial.tools import list_ports

from robot_retarget.bench_stats import TimingStats
from robot_retarget.errors import CommunicationError, HardwareError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.control_table import control_table
from robot_retarget.hardware.servo_registers import (
    EepromLockedError,
    RegisterFinding,
    RegisterWriteError,
    check_servo,
    fix_servo,
)
from robot_retarget.robot.config import BusConfig, RobotConfig
from robot_retarget.robot.servo_models import SERVO_MODELS, servo_model

USB_SERIAL_SYSFS = Path("/sys/bus/usb-serial/devices")


@dataclass(frozen=True)
class SerialPortInfo:
    device: str
    description: str
    hwid: str


def serial_ports() -> list[SerialPortInfo]:
    """Serial ports the OS knows (USB adapters, ACM devices, built-in UARTs)."""
    return [
        SerialPortInfo(pi.device, pi.description or "", pi.hwid or "")
        for pi in sorted(list_ports.comports(), key=lambda x: x.device)
    ]


def latency_timer_path(port: str, sysfs: Path = USB_SERIAL_SYSFS) -> Path:
    """The sysfs latency_timer file of an FTDI USB-serial port (``/dev/ttyUSB0`` → …/ttyUSB0)."""
    name = os.path.basename(os.path.realpath(port))
    return sysfs / name / "latency_timer"


def latency_timer_ms(port: str, sysfs: Path = USB_SERIAL_SYSFS) -> int | None:
    """The FTDI latency timer of ``port`` in ms, or None when the port has none (not FTDI)."""
    path = latency_timer_path(port, sysfs)
    try:
        return int(path.read_text().strip())
    except (OSError, ValueError):
        return None


def latency_advice(port: str, value_ms: int | None, sysfs: Path = USB_SERIAL_SYSFS) -> str:
    """What to do about the latency timer of ``port``."""
    if value_ms is None:
        if not Path(port).exists():
            return f"{port}: no such device (is the adapter plugged in? `doctor` lists ports)"
        return f"{port}: no FTDI latency timer (not an FTDI/U2D2 adapter): nothing to set"
    if value_ms <= 1:
        return f"{port}: latency timer {value_ms} ms: good"
    path = latency_timer_path(port, sysfs)
    return (
        f"{port}: latency timer {value_ms} ms: every reply waits up to {value_ms} ms. Set it to "
        f"1 ms: `echo 1 | sudo tee {path}`; to make it permanent add the udev rule "
        'ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1" '
        "to /etc/udev/rules.d/99-dynamixel.rules"
    )


@dataclass
class BusReport:
    bus: str
    port: str
    protocol: float
    baud_rate: int
    found: dict[int, int] = field(default_factory=dict)  # ID → model number
    missing: list[int] = field(default_factory=list)  # configured, did not answer
    unexpected: list[int] = field(default_factory=list)  # answered, not configured
    mismatched: list[tuple[int, str, int]] = field(default_factory=list)  # ID, expected, found
    cycle: TimingStats | None = None
    cycle_mode: str = ""
    registers: list[RegisterFinding] = field(default_factory=list)  # of the servos found
    fixed: list[RegisterFinding] = field(default_factory=list)  # mismatches written back
    # Servos whose registers could not be fixed (EEPROM locked, a write refused).
    fix_errors: list[HardwareError] = field(default_factory=list)

    @property
    def register_mismatches(self) -> list[RegisterFinding]:
        return [f for f in self.registers if not f.ok]

    def registers_by_servo(self) -> dict[int, list[RegisterFinding]]:
        """The register findings grouped per servo ID, in the config's joint order."""
        out: dict[int, list[RegisterFinding]] = {}
        for f in self.registers:
            out.setdefault(f.servo_id, []).append(f)
        return out

    @property
    def ok(self) -> bool:
        return not (self.missing or self.mismatched or self.register_mismatches)


def model_name(model_number: int) -> str:
    for m in SERVO_MODELS.values():
        if m.model_number == model_number:
            return m.name
    return f"model {model_number}"


def check_bus(
    config: RobotConfig,
    bus_cfg: BusConfig,
    port: str,
    *,
    cycles: int = 200,
    scan_all: bool = False,
    fix_registers: bool = False,
    port_hint: str = "",
) -> BusReport:
    """Ping the bus, compare with the config, check the EEPROM other tools leave behind (and,
    with ``fix_registers``, write the expected values) and time ``cycles`` write+read cycles.

    The cycle writes each servo's own present position back as its goal, so nothing moves.
    ``port_hint`` goes into the error if ``port`` cannot be opened (:class:`DynamixelBus`).
    """
    joints = [j for j in config.joints if j.bus == bus_cfg.name]
    report = BusReport(bus_cfg.name, port, bus_cfg.protocol, bus_cfg.baud_rate)
    bus = DynamixelBus(
        port,
        protocol=bus_cfg.protocol,
        baud_rate=bus_cfg.baud_rate,
        packet_timeout_ms=config.hardware.packet_timeout_ms,
        retries=1,
        name=bus_cfg.name,
        port_hint=port_hint,
    )
    bus.open()
    try:
        configured = {j.servo_id for j in joints}
        ids = range(p.MAX_ID + 1) if scan_all or bus_cfg.protocol == 2.0 else sorted(configured)
        report.found = bus.scan(ids)
        # A servo silent through the scan (its ping and the retry) is asked once more, alone,
        # after the rest: replies lost while a bus settles after its port opened, or to line
        # noise, had reported a servo MISSING that answered the next run.
        for sid in sorted(configured - set(report.found)):
            try:
                report.found[sid] = bus.ping(sid)
            except CommunicationError:
                continue
        report.missing = sorted(configured - set(report.found))
        report.unexpected = sorted(set(report.found) - configured)
        for j in joints:
            expected = servo_model(j.servo_model)
            got = report.found.get(j.servo_id)
            if got is not None and got != expected.model_number:
                report.mismatched.append((j.servo_id, expected.name, got))
        for j in joints:
            if report.found.get(j.servo_id) != servo_model(j.servo_model).model_number:
                continue
            table = control_table(j.servo_model)
            findings = check_servo(bus, j, table)
            bad = [f for f in findings if not f.ok]
            if bad and fix_registers:
                try:
                    still = fix_servo(bus, j, table, bad)
                except (EepromLockedError, RegisterWriteError) as exc:
                    report.fix_errors.append(exc)  # the other servos are still fixed
                else:
                    report.fixed += [
                        f for f in bad if f.register not in {s.register for s in still}
                    ]
                findings = check_servo(bus, j, table)
            report.registers += findings
        present_ids = [j.servo_id for j in joints if j.servo_id in report.found]
        models = [j.servo_model for j in joints if j.servo_id in report.found]
        if present_ids and cycles > 0:
            report.cycle, report.cycle_mode = _time_cycles(bus, present_ids, models, cycles)
    finally:
        bus.close()
    return report


def _time_cycles(
    bus: DynamixelBus, ids: list[int], models: list[str], cycles: int
) -> tuple[TimingStats, str]:
    tables = [control_table(m) for m in models]
    pos = tables[0]["present_position"]
    goal = tables[0]["goal_position"]
    v2 = bus.protocol == 2.0
    fast = v2 and all(t.fast_sync_read for t in tables)
    bulk_ids = [i for i, t in zip(ids, tables, strict=True) if t.bulk_read]
    single_ids = [i for i in ids if i not in bulk_ids]

    def read() -> dict[int, bytes]:
        if v2:
            res = bus.sync_read(pos.address, pos.size, ids, fast=fast)
        else:
            res = bus.bulk_read([(i, pos.address, pos.size) for i in bulk_ids]) if bulk_ids else {}
            for i in single_ids:
                res[i] = bus.read(i, pos.address, pos.size)
        return {i: d for i, (_, d) in res.items()}

    present = read()
    durations = []
    for _ in range(cycles):
        t0 = time.perf_counter()
        bus.sync_write(goal.address, goal.size, {i: present[i][: goal.size] for i in ids})
        read()
        durations.append(time.perf_counter() - t0)
    mode = "sync write + " + (
        ("fast sync read" if fast else "sync read") if v2 else "bulk/single reads"
    )
    return TimingStats.from_seconds(durations), mode
