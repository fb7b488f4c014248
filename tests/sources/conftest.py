"""Fixtures for the source tests: canonical frames and fixture clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"


@pytest.fixture(scope="session")
def motion() -> HumanMotion:
    """Two seconds of the built-in demo clip at 30 fps."""
    return demo_motion(fps=30.0).frames(0, 60)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)
