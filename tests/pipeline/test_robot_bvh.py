from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import MotionFormatError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import read_bvh
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.robot_bvh import write_robot_bvh
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.canonical_skeleton import robot_to_canonical_rotation
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics


def test_bvh_reproduces_robot_link_positions(step: RetargetStep, demo: HumanMotion,
                                             op3: RobotConfig, tmp_path: Path) -> None:  # fmt: skip
    traj = convert_motion(demo.frames(0, 20), step, fps=30.0).trajectory
    clip = read_bvh(write_robot_bvh(tmp_path / "robot.bvh", op3, traj))
    kin = RobotKinematics(op3)
    assert set(clip.names) == set(kin.link_names)
    assert clip.fps == pytest.approx(30.0)
    c = robot_to_canonical_rotation(op3)
    fk = kin.link_transforms(traj.q)[..., :3, 3] @ c.T
    assert traj.root_quat is not None
    assert traj.root_pos is not None
    expected = np.einsum("tij,tlj->tli", quat.to_matrix(traj.root_quat), fk)
    expected += traj.root_pos[:, None]
    order = [clip.names.index(n) for n in kin.link_names]
    np.testing.assert_allclose(clip.global_positions()[:, order], expected, atol=1e-8)


def test_without_root_motion_the_robot_stays_at_the_origin(op3: RobotConfig,
                                                           tmp_path: Path) -> None:  # fmt: skip
    traj = RobotTrajectory(op3.joint_names, np.tile(op3.init_pose, (4, 1)), 10.0)
    clip = read_bvh(write_robot_bvh(tmp_path / "r.bvh", op3, traj))
    np.testing.assert_allclose(clip.global_positions()[:, 0], 0.0, atol=1e-12)
    with pytest.raises(MotionFormatError, match="exists"):
        write_robot_bvh(tmp_path / "r.bvh", op3, traj)


def test_joint_names_must_match(op3: RobotConfig) -> None:
    traj = RobotTrajectory(("a", "b"), np.zeros((2, 2)), 10.0)
    with pytest.raises(ValueError, match="do not match"):
        write_robot_bvh("unused.bvh", op3, traj)
