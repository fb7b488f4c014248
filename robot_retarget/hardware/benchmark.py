"""``bench loop``: cycle time of Sync Write (goal positions) + Sync Read (present positions) of
all servos on the simulated bus, with and without the wire-time model.

The simulated bus runs in its own process (``python -m robot_retarget.sim.dxl_bus``) so it
does not compete with the measured loop for the GIL. Each record also gives the bus's lower bound:
the bytes of
one cycle × 10 bits / baud rate (OP3 at 2 Mbps: 2.24 ms with Sync Read, 1.58 ms with Fast Sync
Read), so the Python overhead is median_ms (no wire model) and the wire-model rows show how
close to the wire limit the loop gets. The ``backend_*`` rows time a whole
DynamixelBackend.send + read_state (every bus, the full present-state block, unit conversion).
"""

from __future__ import annotations

import argparse
import math
import os
import select
import subprocess
import sys
import time
from typing import Any

import numpy as np

from robot_retarget.bench_stats import TimingStats
from robot_retarget.errors import HardwareError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus, buses_from_config
from robot_retarget.hardware.control_table import control_table
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import BusConfig, RobotConfig

HELP = "Sync Write + Sync Read cycle time on the simulated Dynamixel bus (median, p99)."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument("--frames", type=int, default=2000, help="timed cycles per mode")
    parser.add_argument("--warmup", type=int, default=100, help="untimed cycles first")


def cycle_bytes(
    protocol: float, n_servos: int, value_size: int, fast: bool, n_single: int = 0
) -> int:
    """Bytes on the wire for one Sync Write + read cycle (no stuffing). Protocol 1.0: one Bulk
    Read of ``n_servos - n_single`` servos and single reads of the other ``n_single``."""
    if protocol != 2.0:
        n_bulk = n_servos - n_single
        write = 8 + n_servos * (1 + value_size)
        bulk = (7 + 3 * n_bulk + n_bulk * (6 + value_size)) if n_bulk else 0
        return write + bulk + n_single * (8 + 6 + value_size)
    write = 14 + n_servos * (1 + value_size)
    request = 14 + n_servos
    reply = 8 + n_servos * (value_size + 4) if fast else n_servos * (11 + value_size)
    return write + request + reply


class _SimProcess:
    """``python -m robot_retarget.sim.dxl_bus --robot NAME`` in a child process; reads its PORT
    lines."""

    def __init__(self, robot: str, n_buses: int, wire_time: bool) -> None:
        cmd = [sys.executable, "-m", "robot_retarget.sim.dxl_bus", "--robot", robot]
        if wire_time:
            cmd.append("--wire-time")
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.ports: list[str] = []
        if self.proc.stdout is None:
            raise HardwareError("could not start the simulated bus process")
        # Raw reads: a buffered readline() could swallow the second PORT line behind select().
        fd = self.proc.stdout.fileno()
        text = b""
        deadline = time.monotonic() + 20.0
        while len(self.ports) < n_buses and time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.5)
            if not ready:
                continue
            chunk = os.read(fd, 4096)
            if not chunk:
                break
            text += chunk
            lines = text.decode(errors="replace").split("\n")[:-1]
            self.ports = [ln.split()[1] for ln in lines if ln.startswith("PORT ")]
        if len(self.ports) < n_buses:
            err = b""
            if self.proc.stderr is not None and self.proc.poll() is not None:
                err = self.proc.stderr.read()
            self.close()
            raise HardwareError(
                f"the simulated bus did not start ({' '.join(cmd)}): {err.decode(errors='replace')}"
            )

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def _measure(
    bus: DynamixelBus,
    bus_cfg: BusConfig,
    ids: list[int],
    models: list[str],
    fast: bool,
    frames: int,
    warmup: int,
) -> list[float]:
    goal = control_table(models[0])["goal_position"]
    present = control_table(models[0])["present_position"]
    centre = {sid: 2048 if m != "AX-12A" else 512 for sid, m in zip(ids, models, strict=True)}
    delay = control_table(models[0])["return_delay_time"]
    for sid in ids:  # as DynamixelBackend.connect() does: no 500 µs wait before each reply
        bus.write(sid, delay.address, b"\x00")
    durations: list[float] = []
    bulk = [
        (i, present.address, present.size)
        for i, m in zip(ids, models, strict=True)
        if control_table(m).bulk_read
    ]
    single = [i for i, m in zip(ids, models, strict=True) if not control_table(m).bulk_read]
    for k in range(warmup + frames):
        offset = int(100 * math.sin(2 * math.pi * k / 500))
        values = {sid: p.le_bytes(c + offset, goal.size) for sid, c in centre.items()}
        t0 = time.perf_counter()
        bus.sync_write(goal.address, goal.size, values)
        if bus_cfg.protocol == 2.0:
            bus.sync_read(present.address, present.size, ids, fast=fast)
        else:
            if bulk:
                bus.bulk_read(bulk)
            for sid in single:
                bus.read(sid, present.address, present.size)
        t1 = time.perf_counter()
        if k >= warmup:
            durations.append(t1 - t0)
    return durations


def _measure_backend(
    config: RobotConfig, ports: list[str], frames: int, warmup: int
) -> list[float]:
    """DynamixelBackend.send + read_state (all buses, full present-state block) per cycle."""
    buses = buses_from_config(
        config, {b.name: port for b, port in zip(config.buses, ports, strict=True)}
    )
    for bus in buses.values():
        bus.packet_timeout_ms = max(bus.packet_timeout_ms, 20.0)
    backend = DynamixelBackend(config, buses, handle_signals=False)
    durations: list[float] = []
    amplitude = np.minimum(0.05, (config.upper - config.lower) / 4)
    q0 = np.clip(config.init_pose, config.lower + amplitude, config.upper - amplitude)
    with backend:
        backend.send(JointCommand(q0, 0.0))
        for k in range(warmup + frames):
            q = q0 + amplitude * math.sin(2 * math.pi * k / 500)
            t0 = time.perf_counter()
            backend.send(JointCommand(q, k / config.control_rate_hz))
            backend.read_state()
            t1 = time.perf_counter()
            if k >= warmup:
                durations.append(t1 - t0)
    return durations


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.robot.loader import load_robot_config

    config: RobotConfig = load_robot_config(args.robot)
    records: list[dict[str, Any]] = []
    bus_cfg = config.buses[0]
    joints = [j for j in config.joints if j.bus == bus_cfg.name]
    ids = [j.servo_id for j in joints]
    models = [j.servo_model for j in joints]
    fast_ok = bus_cfg.protocol == 2.0 and all(control_table(m).fast_sync_read for m in models)
    variants = [False, True] if fast_ok else [False]
    present_size = control_table(models[0])["present_position"].size
    for wire in (False, True):
        sim = _SimProcess(args.robot, len(config.buses), wire)
        try:
            bus = DynamixelBus(
                sim.ports[0],
                protocol=bus_cfg.protocol,
                baud_rate=bus_cfg.baud_rate,
                packet_timeout_ms=max(config.hardware.packet_timeout_ms, 20.0),
                name=bus_cfg.name,
            )
            bus.open()
            try:
                for fast in variants:
                    durations = _measure(bus, bus_cfg, ids, models, fast, args.frames, args.warmup)
                    stats = TimingStats.from_seconds(durations)
                    n_single = sum(not control_table(m).bulk_read for m in models)
                    n_bytes = cycle_bytes(bus_cfg.protocol, len(ids), present_size, fast, n_single)
                    read = (
                        "fast_sync_read"
                        if fast
                        else ("sync_read" if bus_cfg.protocol == 2.0 else "bulk_read")
                    )
                    records.append(
                        {
                            "mode": f"sync_write+{read}" + ("+wire" if wire else ""),
                            "median_ms": stats.median_ms,
                            "p99_ms": stats.p99_ms,
                            "hz": 1000.0 / stats.median_ms,
                            "wire_limit_ms": n_bytes * 10.0 / bus_cfg.baud_rate * 1e3,
                            "servos": len(ids),
                            "runs": stats.runs,
                        }
                    )
            finally:
                bus.close()
            stats = TimingStats.from_seconds(
                _measure_backend(config, sim.ports, args.frames, args.warmup)
            )
            records.append(
                {
                    "mode": "backend_send+read_state" + ("+wire" if wire else ""),
                    "median_ms": stats.median_ms,
                    "p99_ms": stats.p99_ms,
                    "hz": 1000.0 / stats.median_ms,
                    "servos": config.num_joints,
                    "runs": stats.runs,
                }
            )
        finally:
            sim.close()
    return records
