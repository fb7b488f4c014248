"""Fuzz: ≥ 10⁵ hostile frames (two shards of half each, own seeds) through the live path into
OP3's simulated bus, judged from the bytes the bus received.

Every datagram goes through the UDP source's own decode-and-check path (``handle_packet``), the
control loop (simulated time, 125 Hz), the retargeting step, the safety layer and the real
DynamixelBackend / dynamixel-sdk onto a pseudo-terminal. The verdict does not trust any of
them: it re-parses every Sync Write the simulated servos accepted (its own Protocol 2.0 parser,
byte unstuffing and CRC included), turns the goal ticks back into joint angles with the
XM430's published resolution, and counts goal writes outside the joint limits or faster than
the velocity limit. Both must be 0.
"""

from __future__ import annotations

import collections
import math
import struct
from collections import Counter
from collections.abc import Callable

import numpy as np
import pytest

from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.robot_bus import SimulatedRobotBus
from robot_retarget.sources import wire
from robot_retarget.sources.base import SourceFrame
from robot_retarget.sources.udp import UdpSource
from tests.pipeline.scripted import FakeClock

TIME_LIMIT_S = 300
FRAMES = 100_000
TICKS = 8_000  # 64 s at 125 Hz, 12.5 datagrams per tick (floods come in bursts)
# Run as independent shards (own seed, own start), so that pytest -n spreads them over cores.
SHARDS = 2
_XM430_TICKS_PER_TURN = 4096  # e-Manual: 0–4095 over 360°, 2048 at the centre
_GOAL_POSITION = 116  # XM430 control table address, 4 bytes
_SYNC_WRITE = 0x83


# ----------------------------------------------------------------------------- the sender
class HostileSender:
    """Datagrams, 8 per control tick, mixing good frames of a clip with every kind of abuse."""

    KINDS = (
        "good", "nan", "inf", "huge", "teleport", "flip", "wrong_count", "flood",
        "truncated", "garbage", "stale_seq", "time_backwards", "degenerate", "oscillate",
    )  # fmt: skip

    def __init__(self, motion: HumanMotion, seed: int = 7) -> None:
        self.rng = np.random.default_rng(seed)
        self.pos = motion.positions()
        self.rot = motion.local_quats
        self.root = motion.root_pos
        self.fps = motion.fps
        self.seq = 1
        self.t = 0.0
        self.sent: Counter[str] = Counter()

    def _next(self) -> tuple[int, float, int]:
        self.seq += 1
        self.t += 1.0 / 240.0
        return self.seq, self.t, int(self.t * self.fps) % len(self.pos)

    def _positions(self, values: np.ndarray, seq: int, t: float) -> bytes:
        return wire.encode_binary(wire.KIND_POSITIONS, seq, t, values)

    def _rotations(self, i: int, seq: int, t: float) -> bytes:
        return wire.encode_binary(wire.KIND_ROTATIONS, seq, t, self.rot[i], root=self.root[i])

    def datagrams(self, n: int) -> list[bytes]:
        out = []
        while len(out) < n:
            kind = self.KINDS[int(self.rng.integers(len(self.KINDS)))]
            seq, t, i = self._next()
            good = self.pos[i]
            r = self.rng
            if kind == "good":
                batch = [self._positions(good, seq, t)]
            elif kind in ("nan", "inf", "huge"):
                bad = good.copy()
                value = {"nan": np.nan, "inf": np.inf, "huge": 1e30}[kind]
                bad[r.integers(len(bad)), r.integers(3)] = value * r.choice([-1, 1])
                batch = [self._positions(bad, seq, t)]
            elif kind == "teleport":  # a real pose from elsewhere in the clip, 50 m away
                far = self.pos[int(r.integers(len(self.pos)))] + r.normal(0, 50.0, 3)
                batch = [self._positions(far, seq, t)]
            elif kind == "flip":  # rotations, random joints turned by 180°
                q = self.rot[i].copy()
                for j in r.choice(len(q), size=4, replace=False):
                    axis = r.normal(size=3)
                    axis /= np.linalg.norm(axis)
                    w2, v2 = q[j, 0], q[j, 1:]  # (0, axis) ⊗ q: a half turn about axis
                    q[j] = np.concatenate([[-axis @ v2], w2 * axis + np.cross(axis, v2)])
                batch = [wire.encode_binary(wire.KIND_ROTATIONS, seq, t, q, root=self.root[i])]
            elif kind == "wrong_count":  # JSON: encode_json would write any count it is given
                n_joints = int(r.choice([1, 21, 23, 40]))
                values = r.normal(size=(n_joints, 3))
                batch = [wire.encode_json(wire.KIND_POSITIONS, seq, t, values)]
            elif kind == "flood":  # a burst of valid rotation frames, each a little later
                batch = []
                for _ in range(int(r.integers(10, 30))):
                    seq, t, i = self._next()
                    batch.append(self._rotations(i, seq, t))
            elif kind == "truncated":
                full = self._positions(good, seq, t)
                batch = [full[: int(r.integers(1, len(full)))]]
            elif kind == "garbage":
                batch = [r.integers(0, 256, int(r.integers(1, 400)), dtype=np.uint8).tobytes()]
            elif kind == "stale_seq":
                batch = [self._positions(good, max(seq - int(r.integers(2, 100)), 1), t)]
            elif kind == "time_backwards":
                batch = [self._positions(good, seq, t - float(r.uniform(0.1, 10.0)))]
            elif kind == "degenerate":  # every joint at one point: no bone has a direction
                batch = [self._positions(np.repeat(good[:1], len(good), axis=0), seq, t)]
            else:  # "oscillate": two far-apart poses, alternating frame by frame
                batch = []
                for k in range(6):
                    seq, t, _ = self._next()
                    batch.append(self._rotations(0 if k % 2 else len(self.rot) // 2, seq, t))
            self.sent[kind] += len(batch)
            out.extend(batch)
        return out


class InjectedUdp(UdpSource):
    """The UDP source without a socket: each poll first hands this tick's datagrams to the
    source's own ``handle_packet`` (decode, token, checks, positions → rotations, sequence)."""

    def __init__(self, sender: HostileSender, motion: HumanMotion) -> None:
        super().__init__(skeleton=motion.skeleton, nominal_fps=240.0)
        self.sender = sender
        self.per_tick = FRAMES // TICKS

    def start(self) -> None:
        pass

    def stop(self) -> None:
        pass

    def poll(self, now_s: float) -> list[SourceFrame]:
        for data in self.sender.datagrams(self.per_tick):
            self.handle_packet(data, now_s)
        return super().poll(now_s)


# ----------------------------------------------------------------------------- the verdict
def _unstuff(body: bytes) -> bytes:
    return body.replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")


def _crc16(data: bytes) -> int:
    """CRC-16/BUYPASS (polynomial 0x8005), as the Protocol 2.0 manual specifies."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def goal_writes(packets: list[bytes]) -> list[dict[int, int]]:
    """{servo id: goal tick} of every Protocol 2.0 Sync Write of Goal Position, in order."""
    out = []
    for raw in packets:
        if raw[:4] != b"\xff\xff\xfd\x00" or len(raw) < 10:
            continue
        length = struct.unpack_from("<H", raw, 5)[0]
        assert len(raw) == 7 + length, "the bus accepted a packet of the wrong length"
        assert _crc16(raw[:-2]) == struct.unpack_from("<H", raw, len(raw) - 2)[0]
        instruction = raw[7]
        params = _unstuff(raw[8:-2])
        if instruction != _SYNC_WRITE:
            continue
        address, size = struct.unpack_from("<HH", params, 0)
        if address != _GOAL_POSITION:
            continue
        assert size == 4
        goals = {}
        for k in range(4, len(params), 1 + size):
            goals[params[k]] = struct.unpack_from("<i", params, k + 1)[0]
        out.append(goals)
    return out


def judge(config: RobotConfig, writes: list[dict[int, int]], period_s: float) -> tuple[int, int]:
    """(goal writes outside the joint limits, joint steps faster than the velocity limit)."""
    rad_per_tick = 2 * math.pi / _XM430_TICKS_PER_TURN
    ids = [j.servo_id for j in config.joints]
    for j in config.joints:  # OP3: direction +1 and no zero offset on every joint
        assert j.direction == 1
        assert j.zero_offset_rad == 0.0
    q = np.array([[(w[i] - 2048) * rad_per_tick for i in ids] for w in writes])
    tol = rad_per_tick  # rounding to a tick, either side
    outside = int(np.count_nonzero((q < config.lower - tol) | (q > config.upper + tol)))
    steps = np.abs(np.diff(q, axis=0))
    fast = int(np.count_nonzero(steps > config.max_velocity * period_s + 2 * tol))
    return outside, fast


@pytest.mark.slow
@pytest.mark.parametrize("shard", range(SHARDS))
def test_hostile_frames_never_move_a_servo_out_of_limits_or_too_fast(
    shard: int, step: RetargetStep, op3: RobotConfig, capsys: pytest.CaptureFixture[str]
) -> None:
    motion = demo_motion(fps=30.0)
    sender = HostileSender(motion, seed=7 + shard)
    source = InjectedUdp(sender, motion)
    clock = FakeClock()
    ticks = TICKS // SHARDS
    settings = LoopSettings(duration_s=ticks / op3.control_rate_hz)
    with SimulatedRobotBus(op3, op3.init_pose) as sim:
        for bus in sim.buses.values():
            bus.log.packets = collections.deque()  # keep every packet, not the last few
        backend: DynamixelBackend = sim.backend()
        loop = ControlLoop(step, source, backend, settings, clock=clock.now, sleep=clock.sleep)
        result = loop.run()
        sim.settle()
        packets = [p for bus in sim.buses.values() for p in bus.log.packets]
    writes = goal_writes(packets)
    outside, fast = judge(op3, writes, loop.period_s)
    sent = sum(sender.sent.values())
    report: Callable[[str], None] = print
    with capsys.disabled():
        report(
            f"\nfuzz shard {shard}: {sent} datagrams ({dict(sender.sent)}); source accepted "
            f"{source.stats.accepted}, dropped {dict(source.stats.dropped)}; {len(writes)} goal "
            f"writes on the bus; {outside} outside the limits, {fast} over the velocity limit; "
            f"safety layer clipped {result.safety.commands_clipped} commands"
        )
    assert sent >= FRAMES // SHARDS
    assert set(sender.sent) == set(HostileSender.KINDS)
    assert len(writes) > 0.9 * ticks  # the robot was driven the whole time
    assert outside == 0
    assert fast == 0


def _sync_write(goals: dict[int, int]) -> bytes:
    params = struct.pack("<HH", _GOAL_POSITION, 4)
    for sid, tick in goals.items():
        params += bytes([sid]) + struct.pack("<i", tick)
    return p.build_v2(0xFE, _SYNC_WRITE, params)


def test_the_verdict_sees_a_goal_out_of_limits_and_a_jump(op3: RobotConfig) -> None:
    """The judge itself can fail: one write past a joint's upper limit, one step too fast."""
    ids = [j.servo_id for j in op3.joints]
    home = {sid: 2048 for sid in ids}
    beyond = dict(home)
    k = 0
    beyond[ids[k]] = 2048 + round(op3.upper[k] / (2 * math.pi / 4096)) + 3
    packets = [_sync_write(home), _sync_write(home), _sync_write(beyond)]
    writes = goal_writes(packets)
    assert writes[0] == home
    outside, fast = judge(op3, writes, 1 / op3.control_rate_hz)
    assert outside == 1
    assert fast == 1  # from 0 rad past the upper limit in one period
