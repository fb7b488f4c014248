"""Fixtures for the pipeline tests: OP3, one compiled Retargeter for the session, the copy
model and short motions (the suite-wide conftest gives every test a time limit)."""

from __future__ import annotations

from pathlib import Path

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
