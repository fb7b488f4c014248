from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot_retarget.errors import MotionFormatError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import read_bvh
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.nn.inference import load_model
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.robot_bvh import WORLD_TO_BVH, continuous_zyx, write_robot_bvh
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config


def test_bvh_reproduces_robot_link_positions(step: RetargetStep, demo: HumanMotion,
                                             op3: RobotConfig, tmp_path: Path) -> None:  # fmt: skip
    traj = convert_motion(demo.frames(0, 20), step, fps=30.0).trajectory
    clip = read_bvh(write_robot_bvh(tmp_path / "robot.bvh", op3, traj))
    kin = RobotKinematics(op3)
    assert set(clip.names) == set(kin.link_names)
    assert clip.fps == pytest.approx(30.0)
    fk = kin.link_transforms(traj.q)[..., :3, 3]  # root-link frame
    assert traj.root_quat is not None
    assert traj.root_pos is not None
    world = np.einsum("tij,tlj->tli", quat.to_matrix(traj.root_quat), fk) + traj.root_pos[:, None]
    expected = world @ WORLD_TO_BVH.T  # Z-up world → BVH's Y up, Z forward
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


def test_euler_angles_stay_continuous_through_the_gimbal_region() -> None:
    """A rotation sweeping through pitch ±90°: the raw ZYX triples jump by 180°; the
    continuous ones step by what the rotation moves, and still encode the same rotation."""
    t = np.linspace(0.0, 1.0, 200)
    rot = Rotation.from_euler("ZYX", np.column_stack([0.3 * t, np.pi / 2 * (0.8 + 0.4 * t),
                                                      0.2 + 0 * t]))  # fmt: skip
    raw = rot.as_euler("ZYX")
    smooth = continuous_zyx(raw)
    assert np.abs(np.diff(raw, axis=0)).max() > np.pi / 2  # the jump being fixed
    assert np.abs(np.diff(smooth, axis=0)).max() < 0.05
    again = Rotation.from_euler("ZYX", smooth)
    np.testing.assert_allclose((again.inv() * rot).magnitude(), 0.0, atol=1e-9)


def test_a_poppy_bvh_has_no_euler_jumps(tmp_path: Path) -> None:
    poppy = load_robot_config("poppy_humanoid")
    motion = demo_motion(fps=25.0)
    step = RetargetStep(poppy, load_model("copy"), motion.skeleton)
    traj = convert_motion(motion, step, fps=25.0).trajectory
    clip = read_bvh(write_robot_bvh(tmp_path / "poppy.bvh", poppy, traj))
    jumps = np.abs(np.diff(clip.motion[:, 3:], axis=0))
    assert jumps.max() < 90.0  # degrees between frames 40 ms apart
