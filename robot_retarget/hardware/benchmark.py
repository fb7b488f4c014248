"""``bench loop``: one control cycle on the simulated bus — Sync Write of the goals, then the
read of the present state — as the bare bus calls and as DynamixelBackend does it, side by side
in one run, with and without the simulator's wire-time model.

The simulated bus runs in its own process (``python -m robot_retarget.sim.dxl_bus``) so it does
not compete with the measured loop for the GIL. Both paths run on the same connection, with the
torque on (the simulator moves the servos, as while streaming) and read the same register block
(the backend's per-tick state block); their cycles alternate in rounds so load drifts on a
shared machine hit both alike. Rows:

- ``sdk_sync_write+<read>``: DynamixelBus.sync_write of a dict of goal bytes, then
  sync_read / fast sync read (Protocol 2.0) or bulk read + single reads (Protocol 1.0).
- ``backend_send+read_state``: SafetyLayer.clamp, DynamixelBackend.send and read_state, every
  bus; ``ratio`` is its median (p99) over the bus calls' with the same read instruction.
- ``backend_sequential_buses`` (robots with several buses): the same backend reading its buses
  one after the other instead of at once; ``parallel_vs_sequential`` on the backend row is the
  ratio of their medians.
- ``stage:<name>``: where the backend's cycle goes, per tick: safety clamp, limit check and
  ticks, packet build, SDK write, read (request, wait, framing, CRC), decode to a JointState.

``wire_limit_ms`` is the cycle's bytes × 10 bits / baud rate, summed over the buses.
"""

from __future__ import annotations

import argparse
import math
import os
import select
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from robot_retarget.bench_stats import TimingStats
from robot_retarget.errors import HardwareError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import buses_from_config
from robot_retarget.hardware.control_table import control_table
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.safety import SafetyLayer
from robot_retarget.hardware.stage_timer import StageTimer
from robot_retarget.hardware.state_block import StateBlock
from robot_retarget.hardware.types import JointCommand
from robot_retarget.number_args import non_negative_int, positive_int
from robot_retarget.robot.config import RobotConfig

HELP = "Goal write + state read cycle on the simulated Dynamixel bus: bus calls vs backend."

_SIM_PACKET_TIMEOUT_MS = 200.0
STAGES = ("safety_clamp", "limit_check", "packet_build", "sdk_write", "read", "decode")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument(
        "--frames", type=positive_int, default=2000, help="timed cycles per path and mode"
    )
    parser.add_argument("--warmup", type=non_negative_int, default=100, help="untimed cycles first")
    parser.add_argument(
        "--rounds",
        type=positive_int,
        default=None,
        help="the paths alternate in this many rounds (default: every cycle, so load drifts "
        "on a shared machine hit all paths alike)",
    )
    parser.add_argument(
        "--no-wire", action="store_true", help="only without the wire-time model (quicker)"
    )


def cycle_bytes(
    protocol: float,
    n_servos: int,
    value_size: int,
    fast: bool,
    n_single: int = 0,
    read_size: int | None = None,
) -> int:
    """Bytes on the wire for one Sync Write of ``value_size``-byte goals + a read of
    ``read_size`` bytes per servo (default ``value_size``), no stuffing. Protocol 1.0: one Bulk
    Read of ``n_servos - n_single`` servos and single reads of the other ``n_single``."""
    rs = value_size if read_size is None else read_size
    if protocol != 2.0:
        n_bulk = n_servos - n_single
        write = 8 + n_servos * (1 + value_size)
        bulk = (7 + 3 * n_bulk + n_bulk * (6 + rs)) if n_bulk else 0
        return write + bulk + n_single * (8 + 6 + rs)
    write = 14 + n_servos * (1 + value_size)
    request = 14 + n_servos
    reply = 8 + n_servos * (rs + 4) if fast else n_servos * (11 + rs)
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


class _BusPath:
    """The bare bus calls of one bus: dict of goal bytes → sync_write, then the read."""

    def __init__(self, config: RobotConfig, backend: DynamixelBackend, bus_name: str) -> None:
        joints = [i for i, j in enumerate(config.joints) if j.bus == bus_name]
        self.bus = backend.bus(bus_name)
        self.joints = joints
        self.ids = [config.joints[i].servo_id for i in joints]
        tables = [control_table(config.joints[i].servo_model) for i in joints]
        self.goal = tables[0]["goal_position"]
        self.block: StateBlock = backend.state_block(bus_name)
        self.bulk = [
            (sid, self.block.address, self.block.size)
            for sid, t in zip(self.ids, tables, strict=True)
            if t.bulk_read
        ]
        self.single = [sid for sid, t in zip(self.ids, tables, strict=True) if not t.bulk_read]
        self.v2 = self.bus.protocol == 2.0
        self.can_fast = self.v2 and backend.uses_fast_sync_read(bus_name)

    def cycle(self, ticks: np.ndarray, fast: bool) -> None:
        size = self.goal.size
        pairs = zip(self.ids, self.joints, strict=True)
        values = {sid: p.le_bytes(int(ticks[i]), size) for sid, i in pairs}
        self.bus.sync_write(self.goal.address, size, values)
        if self.v2:
            self.bus.sync_read(self.block.address, self.block.size, self.ids, fast=fast)
            return
        if self.bulk:
            self.bus.bulk_read(self.bulk)
        for sid in self.single:
            self.bus.read(sid, self.block.address, self.block.size)

    def wire_bytes(self, fast: bool) -> int:
        return cycle_bytes(
            self.bus.protocol,
            len(self.ids),
            self.goal.size,
            fast,
            len(self.single),
            read_size=self.block.size,
        )


def _read_name(v2: bool, fast: bool) -> str:
    return "fast_sync_read" if fast else ("sync_read" if v2 else "bulk_read")


def _record(mode: str, durations: list[float], **extra: Any) -> dict[str, Any]:
    stats = TimingStats.from_seconds(durations)
    return {
        "mode": mode,
        "median_ms": stats.median_ms,
        "p99_ms": stats.p99_ms,
        "hz": 1000.0 / stats.median_ms if stats.median_ms > 0 else math.inf,
        **extra,
        "runs": stats.runs,
    }


def _measure_mode(config: RobotConfig, ports: list[str], args: argparse.Namespace, wire: bool
                  ) -> list[dict[str, Any]]:  # fmt: skip
    buses = buses_from_config(
        config, {b.name: port for b, port in zip(config.buses, ports, strict=True)}
    )
    for bus in buses.values():
        # The simulator is a process on a shared machine: under load it can miss 20 ms. A late
        # reply then shows in p99 instead of stopping the run (retries are counted below).
        bus.packet_timeout_ms = max(bus.packet_timeout_ms, _SIM_PACKET_TIMEOUT_MS)
    backend = DynamixelBackend(config, buses, handle_signals=False)
    safety = SafetyLayer(config, backend)
    amplitude = np.minimum(0.05, (config.upper - config.lower) / 4)
    q0 = np.clip(config.init_pose, config.lower + amplitude, config.upper - amplitude)
    dt = 1.0 / config.control_rate_hz
    suffix = "+wire" if wire else ""
    with safety:
        safety.send(JointCommand(q0, 0.0))  # torque on, ramp to q0
        paths = [_BusPath(config, backend, b.name) for b in config.buses]
        v2 = all(pt.v2 for pt in paths)
        fast_variants = [False, True] if v2 and all(pt.can_fast for pt in paths) else [False]
        backend_fast = v2 and all(pt.can_fast for pt in paths)
        k = 0

        def q_at(step: int) -> np.ndarray:
            return q0 + amplitude * math.sin(2 * math.pi * step / 500)

        def raw_cycle(fast: bool) -> Callable[[], None]:
            def run() -> None:
                ticks = backend.units.to_ticks(q_at(k))
                for pt in paths:
                    pt.cycle(ticks, fast)

            return run

        timer = StageTimer()

        def backend_cycle() -> None:
            timer.start()
            safe = safety.clamp(JointCommand(q_at(k), k * dt))
            timer.lap("safety_clamp")
            backend.send(safe)
            backend.read_state()
            timer.commit()

        runners: dict[str, Callable[[], None]] = {
            f"sdk_sync_write+{_read_name(v2, f)}{suffix}": raw_cycle(f) for f in fast_variants
        }
        runners[f"backend_send+read_state{suffix}"] = backend_cycle
        if len(paths) > 1:

            def sequential_cycle() -> None:  # not in the stage rows: those are the default's
                stages, backend.stage_timer = backend.stage_timer, None
                backend.parallel_buses = False
                try:
                    backend.send(safety.clamp(JointCommand(q_at(k), k * dt)))
                    backend.read_state()
                finally:
                    backend.parallel_buses = True
                    backend.stage_timer = stages

            runners[f"backend_sequential_buses{suffix}"] = sequential_cycle
        durations: dict[str, list[float]] = {name: [] for name in runners}
        for _ in range(args.warmup):
            for fn in runners.values():
                fn()
                k += 1
        backend.stage_timer = timer
        timer.samples.clear()
        rounds = max(1, min(args.rounds or args.frames, args.frames))
        per_round = max(1, args.frames // rounds)
        for _ in range(rounds):
            for name, fn in runners.items():
                out = durations[name]
                for _ in range(per_round):
                    t0 = time.perf_counter()
                    fn()
                    out.append(time.perf_counter() - t0)
                    k += 1
        backend.stage_timer = None
        wire_ms = {
            f: sum(pt.wire_bytes(f) for pt in paths) * 10.0 / paths[0].bus.baud_rate * 1e3
            for f in (False, True)
        }
        if len({pt.bus.baud_rate for pt in paths}) > 1:  # buses at different rates: per bus
            wire_ms = {
                f: sum(pt.wire_bytes(f) * 10.0 / pt.bus.baud_rate * 1e3 for pt in paths)
                for f in (False, True)
            }
    records: list[dict[str, Any]] = []
    raw_median: dict[bool, tuple[float, float]] = {}
    for f in fast_variants:
        name = f"sdk_sync_write+{_read_name(v2, f)}{suffix}"
        rec = _record(name, durations[name], wire_limit_ms=wire_ms[f], servos=config.num_joints)
        raw_median[f] = (rec["median_ms"], rec["p99_ms"])
        records.append(rec)
    name = f"backend_send+read_state{suffix}"
    rec = _record(name, durations[name], wire_limit_ms=wire_ms[backend_fast])
    base = raw_median[backend_fast]
    rec["ratio_median"] = rec["median_ms"] / base[0]
    rec["ratio_p99"] = rec["p99_ms"] / base[1]
    rec["servos"] = config.num_joints
    rec["retries"] = sum(b.stats.retries for b in buses.values())
    records.append(rec)
    name = f"backend_sequential_buses{suffix}"
    if name in durations:
        seq = _record(name, durations[name], wire_limit_ms=wire_ms[backend_fast])
        # parallel / sequential: below 1 where reading the buses at once pays
        rec["parallel_vs_sequential"] = rec["median_ms"] / seq["median_ms"]
        records.append(seq)
    for stage in STAGES:
        if stage in timer.samples:
            records.append(_record(f"stage:{stage}{suffix}", timer.samples[stage]))
    return records


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.robot.loader import load_robot_config

    config: RobotConfig = load_robot_config(args.robot)
    records: list[dict[str, Any]] = []
    for wire in (False,) if args.no_wire else (False, True):
        sim = _SimProcess(args.robot, len(config.buses), wire)
        try:
            records += _measure_mode(config, sim.ports, args, wire)
        finally:
            sim.close()
    return records
