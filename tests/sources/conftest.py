"""Fixtures for the source tests: a per-test time limit, canonical frames, fixture clips."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
TEST_TIME_LIMIT_S = 30


@pytest.fixture(autouse=True)
def _time_limit() -> Iterator[None]:
    """Fail (not hang) a test that runs past TEST_TIME_LIMIT_S."""

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
def motion() -> HumanMotion:
    """Two seconds of the built-in demo clip at 30 fps."""
    return demo_motion(fps=30.0).frames(0, 60)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)
