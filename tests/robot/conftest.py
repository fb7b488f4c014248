"""Fixtures for the robot tests: the repo's robot configs and the shared robot description data."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs" / "robots"


@pytest.fixture(scope="session")
def config_dir() -> Path:
    """The repository's configs/robots folder."""
    return CONFIG_DIR


@pytest.fixture(scope="session")
def op3_text() -> str:
    """The text of configs/robots/op3/op3.yaml, for writing broken variants."""
    return (CONFIG_DIR / "op3" / "op3.yaml").read_text(encoding="utf-8")


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture(scope="session")
def poppy() -> RobotConfig:
    return load_robot_config("poppy_humanoid")


@pytest.fixture(scope="session")
def robots_data(shared_data_dir: Path) -> Path:
    """../shared/data/robots; skips when the robot descriptions are absent."""
    path = shared_data_dir / "robots"
    if not path.is_dir():
        pytest.skip(f"robot description data not found at {path}")
    return path


@pytest.fixture(scope="session")
def op3_urdf(robots_data: Path) -> Path:
    return _require(robots_data / "robotis_op3" / "urdf" / "robotis_op3.expanded.urdf")


@pytest.fixture(scope="session")
def poppy_urdf(robots_data: Path) -> Path:
    return _require(robots_data / "poppy_humanoid" / "Poppy_Humanoid.URDF")


def _require(path: Path) -> Path:
    if not path.is_file():
        pytest.skip(f"{path} not found in the shared data")
    return path
