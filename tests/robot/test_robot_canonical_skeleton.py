"""The robot's canonical skeleton: canonical joints, T-pose axes, bone lengths from robot FK."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robot_retarget.errors import ConfigError
from robot_retarget.robot.canonical_skeleton import (
    REQUIRED_BONES,
    robot_canonical_skeleton,
    robot_to_canonical_rotation,
)
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS


def _fk_lengths(config: RobotConfig) -> dict[tuple[str, str], float]:
    kin = RobotKinematics(config)
    zero = np.zeros(config.num_joints)
    out = {}
    for b in config.bones:
        p = kin.frame_positions(zero, [b.start_frame, b.end_frame])
        out[(b.canonical, b.canonical_end)] = float(np.linalg.norm(p[1] - p[0]))
    return out


@pytest.mark.parametrize("robot", ["op3", "poppy"])
def test_bone_lengths_match_robot_fk(robot: str, request: pytest.FixtureRequest) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    skeleton = robot_canonical_skeleton(config)
    assert skeleton.names == CANONICAL_JOINTS
    assert skeleton.parents == CANONICAL_PARENTS
    rest = skeleton.rest_positions()
    lengths = _fk_lengths(config)
    for start, end in REQUIRED_BONES:
        got = np.linalg.norm(
            rest[CANONICAL_JOINTS.index(end)] - rest[CANONICAL_JOINTS.index(start)]
        )
        assert got == pytest.approx(lengths[(start, end)], abs=1e-12), f"{start}→{end}"
    # Shoulder and hip widths are the robot's.
    kin = RobotKinematics(config)
    zero = np.zeros(config.num_joints)
    bone = {(b.canonical, b.canonical_end): b for b in config.bones}
    for left, right in (("LeftArm", "RightArm"), ("LeftUpLeg", "RightUpLeg")):
        frames = [
            bone[(left, left.replace("Arm", "ForeArm").replace("UpLeg", "Leg"))].start_frame,
            bone[(right, right.replace("Arm", "ForeArm").replace("UpLeg", "Leg"))].start_frame,
        ]
        robot_width = np.linalg.norm(np.subtract(*kin.frame_positions(zero, frames)))
        width = np.linalg.norm(
            rest[CANONICAL_JOINTS.index(left)] - rest[CANONICAL_JOINTS.index(right)]
        )
        assert width == pytest.approx(robot_width, abs=1e-4)


@pytest.mark.parametrize("robot", ["op3", "poppy"])
def test_canonical_t_pose_axes(robot: str, request: pytest.FixtureRequest) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    rest = robot_canonical_skeleton(config).rest_positions()
    p = dict(zip(CANONICAL_JOINTS, rest, strict=True))
    assert p["Head"][1] > p["Neck"][1] > p["Hips"][1]  # Y up
    assert p["LeftHand"][0] > p["LeftArm"][0] > 0 > p["RightArm"][0] > p["RightHand"][0]
    assert p["LeftToeBase"][2] > p["LeftFoot"][2]  # facing +Z
    assert p["LeftFoot"][1] < p["LeftLeg"][1] < p["LeftUpLeg"][1] < 0
    rot = robot_to_canonical_rotation(config)
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)


def test_missing_bone_is_a_config_error(op3: RobotConfig) -> None:
    bones = tuple(b for b in op3.bones if b.canonical != "LeftForeArm")
    broken = dataclasses.replace(op3, bones=bones)
    with pytest.raises(ConfigError, match="LeftForeArm→LeftHand") as info:
        robot_canonical_skeleton(broken)
    assert info.value.key == "bones"
