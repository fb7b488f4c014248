"""Fixtures for the hardware tests: robot configs and simulated buses on pseudo-terminals.

Configs: the real ones from configs/robots when they load, otherwise fixture configs with the
same buses, IDs and servo models (from ../shared/data/robots/*/README.md: OP3 20 × XM430-W350
IDs 1–20 at 2 Mbps, Protocol 2.0; Poppy Humanoid 25 servos on two Protocol 1.0 buses at 1 Mbps).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.robot.config import BusConfig, HardwareSettings, JointConfig, RobotConfig
from robot_retarget.sim.dxl_bus import SimulatedBus, buses_for_robot

REPO = Path(__file__).resolve().parents[2]


def _joint(
    name: str, sid: int, model: str, bus: str, lo: float, hi: float, d: int = 1
) -> JointConfig:
    vmax = {"XM430-W350": 4.8, "MX-28": 5.7, "MX-64": 6.5, "AX-12A": 6.1}[model]
    return JointConfig(
        name=name,
        parent_link="base",
        child_link=f"{name}_link",
        origin_xyz=(0.0, 0.0, 0.0),
        origin_rpy=(0.0, 0.0, 0.0),
        axis=(0.0, 0.0, 1.0),
        lower_rad=lo,
        upper_rad=hi,
        max_velocity_rad_s=vmax,
        servo_id=sid,
        servo_model=model,
        bus=bus,
        direction=d,
    )


def fixture_op3() -> RobotConfig:
    joints = tuple(
        _joint(f"j{sid:02d}", sid, "XM430-W350", "main", -2.0, 2.0, -1 if sid % 3 == 0 else 1)
        for sid in range(1, 21)
    )
    return _robot("op3_fixture", (BusConfig("main", 2.0, 2_000_000, "/dev/ttyUSB0"),), joints)


# (name, id, model, bus, lower deg, upper deg, direction) from the Poppy README joint table.
_POPPY = (
    ("r_hip_x", 21, "MX-28", "lower", -28.5, 30, 1),
    ("r_hip_z", 22, "MX-28", "lower", -90, 25, -1),
    ("r_hip_y", 23, "MX-64", "lower", -85, 105, -1),
    ("r_knee_y", 24, "MX-28", "lower", -134, 3.5, -1),
    ("r_ankle_y", 25, "MX-28", "lower", -45, 45, -1),
    ("l_hip_x", 11, "MX-28", "lower", -30, 28.5, 1),
    ("l_hip_z", 12, "MX-28", "lower", -25, 90, -1),
    ("l_hip_y", 13, "MX-64", "lower", -104, 84, 1),
    ("l_knee_y", 14, "MX-28", "lower", -3.5, 134, 1),
    ("l_ankle_y", 15, "MX-28", "lower", -45, 45, 1),
    ("abs_y", 31, "MX-64", "upper", -50, 12, -1),
    ("abs_x", 32, "MX-64", "upper", -45, 45, -1),
    ("abs_z", 33, "MX-28", "upper", -90, 90, 1),
    ("bust_y", 34, "MX-28", "upper", -67, 27, -1),
    ("bust_x", 35, "MX-28", "upper", -40, 40, -1),
    ("head_z", 36, "AX-12A", "upper", -90, 90, 1),
    ("head_y", 37, "AX-12A", "upper", -45, 6, -1),
    ("l_shoulder_y", 41, "MX-28", "upper", -120, 155, 1),
    ("l_shoulder_x", 42, "MX-28", "upper", -105, 110, -1),
    ("l_arm_z", 43, "MX-28", "upper", -105, 105, -1),
    ("l_elbow_y", 44, "MX-28", "upper", -148, 1, 1),
    ("r_shoulder_y", 51, "MX-28", "upper", -155, 120, -1),
    ("r_shoulder_x", 52, "MX-28", "upper", -110, 105, -1),
    ("r_arm_z", 53, "MX-28", "upper", -105, 105, -1),
    ("r_elbow_y", 54, "MX-28", "upper", -1, 148, -1),
)


def fixture_poppy() -> RobotConfig:
    joints = tuple(
        _joint(n, sid, m, b, math.radians(lo), math.radians(hi), d)
        for n, sid, m, b, lo, hi, d in _POPPY
    )
    buses = (
        BusConfig("upper", 1.0, 1_000_000, "/dev/ttyACM0"),
        BusConfig("lower", 1.0, 1_000_000, "/dev/ttyACM1"),
    )
    return _robot("poppy_fixture", buses, joints)


def _robot(name: str, buses: tuple[BusConfig, ...], joints: tuple[JointConfig, ...]) -> RobotConfig:
    n = len(joints)
    return RobotConfig(
        name=name,
        description="hardware test fixture",
        source_path=None,
        root_link="base",
        up_axis=(0.0, 0.0, 1.0),
        forward_axis=(1.0, 0.0, 0.0),
        buses=buses,
        joints=joints,
        frames=(),
        bones=(),
        init_pose=np.zeros(n),
        safe_pose=np.zeros(n),
        control_rate_hz=100.0,
        hardware=HardwareSettings(packet_timeout_ms=4.0, return_delay_us=0),
    )


def load_or_fixture(name: str) -> RobotConfig:
    """The real config ``configs/robots/<name>.yaml`` when it exists (a broken one fails the
    tests), else the fixture with the same buses, IDs and models."""
    if not (REPO / "configs" / "robots" / name / f"{name}.yaml").is_file():
        return fixture_op3() if name == "op3" else fixture_poppy()
    from robot_retarget.robot.loader import load_robot_config

    return load_robot_config(name)


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_or_fixture("op3")


@pytest.fixture(scope="session")
def poppy() -> RobotConfig:
    return load_or_fixture("poppy_humanoid")


def start_sim(config: RobotConfig, wire_time: bool = False) -> dict[str, SimulatedBus]:
    sims = buses_for_robot(config, wire_time=wire_time)
    for s in sims.values():
        s.start()
    return sims


def client_buses(
    config: RobotConfig, sims: dict[str, SimulatedBus], retries: int = 2
) -> dict[str, DynamixelBus]:
    return {
        b.name: DynamixelBus(
            sims[b.name].port or "",
            protocol=b.protocol,
            baud_rate=b.baud_rate,
            # Roomier than the config's 4 ms: the in-process bus shares 2 busy cores in CI.
            packet_timeout_ms=max(config.hardware.packet_timeout_ms, 20.0),
            retries=retries,
            name=b.name,
        )
        for b in config.buses
    }


@pytest.fixture
def op3_sim(op3: RobotConfig) -> Iterator[dict[str, SimulatedBus]]:
    sims = start_sim(op3)
    yield sims
    for s in sims.values():
        s.stop()


@pytest.fixture
def poppy_sim(poppy: RobotConfig) -> Iterator[dict[str, SimulatedBus]]:
    sims = start_sim(poppy)
    yield sims
    for s in sims.values():
        s.stop()


@pytest.fixture
def make_buses() -> Callable[..., dict[str, DynamixelBus]]:
    """``make_buses(config, sims, retries=2)``: one client DynamixelBus per simulated bus."""
    return client_buses
