"""DynamixelBus against the simulated bus on a pty: instructions, retries, faults, stuffing."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from robot_retarget.errors import CommunicationError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus, PortUnavailableError, buses_from_config
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.dxl_bus import SimulatedBus
from robot_retarget.sim.servo import SimServo


@pytest.fixture
def xm_sim() -> Iterator[SimulatedBus]:
    with SimulatedBus(
        [SimServo(i, "XM430-W350") for i in (1, 2, 3)], protocol=2.0, baud_rate=2_000_000
    ) as sim:
        yield sim


@pytest.fixture
def xm_bus(xm_sim: SimulatedBus) -> Iterator[DynamixelBus]:
    bus = DynamixelBus(xm_sim.port or "", protocol=2.0, baud_rate=2_000_000, packet_timeout_ms=20)
    bus.open()
    yield bus
    bus.close()


@pytest.fixture
def p1_sim() -> Iterator[SimulatedBus]:
    servos = [SimServo(11, "MX-28"), SimServo(13, "MX-64"), SimServo(36, "AX-12A")]
    with SimulatedBus(servos, protocol=1.0, baud_rate=1_000_000) as sim:
        yield sim


@pytest.fixture
def p1_bus(p1_sim: SimulatedBus) -> Iterator[DynamixelBus]:
    bus = DynamixelBus(p1_sim.port or "", protocol=1.0, baud_rate=1_000_000, packet_timeout_ms=20)
    bus.open()
    yield bus
    bus.close()


def test_ping_read_write_v2(xm_bus: DynamixelBus, xm_sim: SimulatedBus) -> None:
    assert xm_bus.ping(2) == 1020
    assert xm_bus.write(2, 9, b"\x00") == 0
    assert xm_sim.servos[2].get("return_delay_time") == 0
    err, data = xm_bus.read(2, 132, 4)
    assert err == 0
    assert p.from_le(data) == 2048
    assert xm_bus.scan() == {1: 1020, 2: 1020, 3: 1020}


def test_sync_write_and_both_sync_reads(xm_bus: DynamixelBus, xm_sim: SimulatedBus) -> None:
    values = {1: p.le_bytes(1000, 4), 2: p.le_bytes(2000, 4), 3: p.le_bytes(3000, 4)}
    xm_bus.sync_write(116, 4, values)
    for fast in (False, True):
        res = xm_bus.sync_read(116, 4, [1, 2, 3], fast=fast)
        assert {i: p.from_le(d) for i, (_, d) in res.items()} == {1: 1000, 2: 2000, 3: 3000}


def test_bulk_read_and_single_reads_v1(p1_bus: DynamixelBus, p1_sim: SimulatedBus) -> None:
    assert p1_bus.ping(13) == 310
    assert p1_bus.ping(36) == 12
    p1_bus.sync_write(30, 2, {11: p.le_bytes(1000, 2), 13: p.le_bytes(3000, 2)})
    res = p1_bus.bulk_read([(11, 30, 2), (13, 30, 2)])
    assert {i: p.from_le(d) for i, (_, d) in res.items()} == {11: 1000, 13: 3000}
    with pytest.raises(CommunicationError):  # the AX has no Bulk Read: it never answers
        p1_bus.bulk_read([(36, 30, 2)])
    assert p.from_le(p1_bus.read(36, 0, 2)[1]) == 12
    assert p1_bus.scan([11, 12, 13, 36]) == {11: 29, 13: 310, 36: 12}


def test_dropped_reply_is_retried(xm_bus: DynamixelBus, xm_sim: SimulatedBus) -> None:
    xm_sim.faults.drop_replies = 1
    assert xm_bus.ping(1) == 1020
    assert xm_bus.stats.retries >= 1
    assert xm_bus.stats.failures == 0


def test_corrupt_reply_is_retried(xm_bus: DynamixelBus, xm_sim: SimulatedBus) -> None:
    xm_sim.faults.corrupt_replies = 1
    res = xm_bus.sync_read(132, 4, [1, 2, 3])
    assert len(res) == 3
    assert xm_bus.stats.retries >= 1


def test_late_reply_is_retried(xm_sim: SimulatedBus) -> None:
    bus = DynamixelBus(
        xm_sim.port or "", protocol=2.0, baud_rate=2_000_000, packet_timeout_ms=20, retries=10
    )
    bus.open()
    xm_sim.faults.late_replies, xm_sim.faults.late_reply_s = 1, 0.1
    assert bus.ping(3) == 1020
    assert bus.stats.retries >= 1
    bus.close()


def test_repeated_failures_raise_fast(xm_bus: DynamixelBus, xm_sim: SimulatedBus) -> None:
    xm_sim.faults.drop_replies = 100
    with pytest.raises(CommunicationError, match="failed 3 times"):
        xm_bus.sync_read(132, 4, [1, 2, 3])
    assert xm_bus.stats.failures == 1  # bounded: three attempts, then the error
    assert xm_sim.faults.drop_replies == 100 - 3 * 3  # 3 servos' replies dropped per attempt


def test_unplugged_port_fails_fast_with_a_clear_error(
    xm_bus: DynamixelBus, xm_sim: SimulatedBus
) -> None:
    xm_sim.unplug()
    with pytest.raises(CommunicationError, match=r"unplugged|failed"):
        xm_bus.ping(1)
    assert xm_bus.stats.retries == 0  # an unplugged port is not retried


def test_missing_port_is_a_clear_error() -> None:
    bus = DynamixelBus("/dev/does-not-exist", protocol=2.0, baud_rate=2_000_000)
    with pytest.raises(PortUnavailableError, match="dialout") as info:
        bus.open()
    assert info.value.port == "/dev/does-not-exist"


def test_goal_needing_byte_stuffing_arrives_intact(
    xm_bus: DynamixelBus, xm_sim: SimulatedBus
) -> None:
    assert xm_bus.write(2, 11, b"\x04") == 0  # extended position mode: negative goals allowed
    goal = -131073  # little endian FF FF FD FF
    sent = xm_bus.sync_write(116, 4, {1: p.le_bytes(0, 4), 2: p.le_bytes(goal, 4)})
    assert b"\xff\xff\xfd\xfd" in sent  # stuffed on the wire
    xm_sim.settle()
    assert xm_sim.servos[2].get("goal_position") == goal
    assert xm_sim.log.packets[-1] == sent
    assert not xm_sim.log.rejected
    res = xm_bus.sync_read(116, 4, [2])  # the status packet is stuffed too
    assert p.from_le(res[2][1], signed=True) == goal


def test_bus_must_be_open() -> None:
    bus = DynamixelBus("/dev/null", protocol=2.0, baud_rate=2_000_000)
    with pytest.raises(PortUnavailableError, match="open"):
        bus.ping(1)
    with pytest.raises(ValueError, match="protocol"):
        DynamixelBus("/dev/null", protocol=3.0, baud_rate=1)


def test_buses_from_config(poppy: RobotConfig) -> None:
    buses = buses_from_config(poppy, {poppy.buses[0].name: "/dev/ttyX"})
    first, second = (buses[b.name] for b in poppy.buses)
    assert first.port_name == "/dev/ttyX"
    assert second.port_name == poppy.buses[1].default_port
    assert first.protocol == 1.0
    assert first.baud_rate == poppy.buses[0].baud_rate
    assert first.packet_timeout_ms == poppy.hardware.packet_timeout_ms
    assert not first.is_open
