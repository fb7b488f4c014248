"""Fixtures for the simulator tests: simulated buses with a few servos and SDK clients on them."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import dynamixel_sdk as sdk
import pytest

from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.dxl_bus import SimulatedBus
from robot_retarget.sim.servo import SimServo


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture
def v2_bus() -> Iterator[SimulatedBus]:
    with SimulatedBus(
        [SimServo(i, "XM430-W350") for i in (1, 2, 5)], protocol=2.0, baud_rate=2_000_000
    ) as bus:
        yield bus


@pytest.fixture
def v1_bus() -> Iterator[SimulatedBus]:
    servos = [SimServo(11, "MX-28"), SimServo(13, "MX-64"), SimServo(36, "AX-12A")]
    with SimulatedBus(servos, protocol=1.0, baud_rate=1_000_000) as bus:
        yield bus


def _open(bus: SimulatedBus, protocol: float) -> tuple[Any, Any]:
    port = sdk.PortHandler(bus.port)
    assert port.openPort()
    assert port.setBaudRate(bus.baud_rate)
    return port, sdk.PacketHandler(protocol)


@pytest.fixture
def v2_client(v2_bus: SimulatedBus) -> Iterator[tuple[Any, Any]]:
    port, ph = _open(v2_bus, 2.0)
    yield port, ph
    port.closePort()


@pytest.fixture
def v1_client(v1_bus: SimulatedBus) -> Iterator[tuple[Any, Any]]:
    port, ph = _open(v1_bus, 1.0)
    yield port, ph
    port.closePort()
