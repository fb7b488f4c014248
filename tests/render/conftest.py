"""Fixtures for the preview tests: OP3 and a short human clip."""

from __future__ import annotations

import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture(scope="session")
def clip() -> HumanMotion:
    return demo_motion(fps=10.0).frames(0, 6)
