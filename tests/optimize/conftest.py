"""Fixtures for the optimizer tests: robots and retargeters, built (and JIT-compiled) once.

``op3`` is the project's configs/robots/op3/op3.yaml; ``twist_arm`` a small two-arm robot built from
the dataclasses, with a forearm roll joint of ±172°, so that the twist bound (not a joint limit)
is what stops a twisted forearm.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.optimize import Retargeter
from robot_retarget.robot.config import (
    BoneConfig,
    BusConfig,
    FrameConfig,
    JointConfig,
    RobotConfig,
)
from robot_retarget.robot.loader import load_robot_config

# name, parent link, child link, axis, origin xyz, lower, upper (rad)
_ARM: tuple[tuple[str, str, str, tuple[float, ...], tuple[float, ...], float, float], ...] = (
    ("l_sho_pitch", "torso", "l_sho_link", (0, 1, 0), (0.0, 0.08, 0.2), -3.0, 3.0),
    ("l_sho_roll", "l_sho_link", "l_upper", (-1, 0, 0), (0.0, 0.0, 0.0), -1.6, 1.6),
    ("l_el", "l_upper", "l_elbow", (1, 0, 0), (0.0, 0.1, 0.0), -2.4, 0.2),
    ("l_fore_roll", "l_elbow", "l_fore", (0, 1, 0), (0.0, 0.0, 0.0), -3.0, 3.0),
    ("r_sho_pitch", "torso", "r_sho_link", (0, -1, 0), (0.0, -0.08, 0.2), -3.0, 3.0),
    ("r_sho_roll", "r_sho_link", "r_upper", (-1, 0, 0), (0.0, 0.0, 0.0), -1.6, 1.6),
    ("r_el", "r_upper", "r_elbow", (1, 0, 0), (0.0, -0.1, 0.0), -0.2, 2.4),
    ("r_fore_roll", "r_elbow", "r_fore", (0, -1, 0), (0.0, 0.0, 0.0), -3.0, 3.0),
)


def make_twist_arm(retarget: dict[str, float] | None = None) -> RobotConfig:
    joints = tuple(
        JointConfig(
            name=name,
            parent_link=parent,
            child_link=child,
            origin_xyz=(xyz[0], xyz[1], xyz[2]),
            origin_rpy=(0.0, 0.0, 0.0),
            axis=(float(axis[0]), float(axis[1]), float(axis[2])),
            lower_rad=lo,
            upper_rad=hi,
            max_velocity_rad_s=5.0,
            servo_id=i + 1,
            servo_model="XM430-W350",
            bus="main",
        )
        for i, (name, parent, child, axis, xyz, lo, hi) in enumerate(_ARM)
    )
    zero = np.zeros(len(joints))
    return RobotConfig(
        name="twist_arm",
        description="two arms with a forearm roll joint (tests)",
        source_path=None,
        root_link="torso",
        up_axis=(0.0, 0.0, 1.0),
        forward_axis=(1.0, 0.0, 0.0),
        buses=(BusConfig("main", 2.0, 2_000_000, "/dev/null"),),
        joints=joints,
        frames=(
            FrameConfig("l_hand", "l_fore", (0.0, 0.1, 0.0)),
            FrameConfig("r_hand", "r_fore", (0.0, -0.1, 0.0)),
        ),
        bones=(
            BoneConfig("LeftArm", "LeftForeArm", "l_upper", "l_elbow"),
            BoneConfig("LeftForeArm", "LeftHand", "l_fore", "l_hand"),
            BoneConfig("RightArm", "RightForeArm", "r_upper", "r_elbow"),
            BoneConfig("RightForeArm", "RightHand", "r_fore", "r_hand"),
        ),
        init_pose=zero,
        safe_pose=zero.copy(),
        retarget=retarget or {},
    )


@pytest.fixture(scope="session")
def twist_arm() -> RobotConfig:
    return make_twist_arm()


@pytest.fixture(scope="session")
def twist_arm_factory() -> Callable[[dict[str, float]], RobotConfig]:
    """twist_arm with a given ``retarget`` section."""
    return make_twist_arm


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture(scope="session")
def poppy() -> RobotConfig:
    return load_robot_config("poppy_humanoid")


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One JIT cache for the session: each robot compiles once."""
    return tmp_path_factory.mktemp("retarget_cache")


@pytest.fixture(scope="session")
def twist_retargeter(twist_arm: RobotConfig, cache_dir: Path) -> Retargeter:
    return Retargeter(twist_arm, cache_dir=cache_dir)


@pytest.fixture(scope="session")
def op3_retargeter(op3: RobotConfig, cache_dir: Path) -> Retargeter:
    return Retargeter(op3, cache_dir=cache_dir)
