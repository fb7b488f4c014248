"""Fixtures for the pipeline tests: OP3, one compiled Retargeter for the session, the copy
model, short motions and a per-test time limit (nothing may hang CI)."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn.inference import LoadedModel, load_model
from robot_retarget.optimize import Retargeter
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
TEST_TIME_LIMIT_S = 60


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
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture(scope="session")
def copy_model() -> LoadedModel:
    return load_model("copy")


@pytest.fixture(scope="session")
def retargeter(op3: RobotConfig) -> Retargeter:
    r = Retargeter(op3)
    r.warm_up()
    return r


@pytest.fixture(scope="session")
def demo() -> HumanMotion:
    """The first 2 s of the built-in demo clip at 30 fps."""
    return demo_motion(fps=30.0).frames(0, 61)


@pytest.fixture
def step(op3: RobotConfig, copy_model: LoadedModel, retargeter: Retargeter,
         demo: HumanMotion) -> RetargetStep:  # fmt: skip
    s = RetargetStep(op3, copy_model, demo.skeleton, retargeter=retargeter)
    s.reset()
    return s


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(11)
