"""Fixtures for the preview tests: OP3, a short human clip and a per-test time limit."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from types import FrameType

import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config

TEST_TIME_LIMIT_S = 60


@pytest.fixture(autouse=True)
def _time_limit() -> Iterator[None]:
    def _expire(signum: int, frame: FrameType | None) -> None:
        raise TimeoutError(f"test exceeded {TEST_TIME_LIMIT_S} s")

    old = signal.signal(signal.SIGALRM, _expire)
    signal.alarm(TEST_TIME_LIMIT_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture(scope="session")
def clip() -> HumanMotion:
    return demo_motion(fps=10.0).frames(0, 6)
