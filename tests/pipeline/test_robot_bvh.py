from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot_retarget.errors import MotionFormatError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import read_bvh
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.nn.inference import load_model
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.robot_bvh import (
    WORLD_TO_BVH,
    continuous_euler,
    robot_bvh_clip,
    write_robot_bvh,
)
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.canonical_skeleton import robot_to_canonical_rotation
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
    smooth = continuous_euler(raw)
    assert np.abs(np.diff(raw, axis=0)).max() > np.pi / 2  # the jump being fixed
    assert np.abs(np.diff(smooth, axis=0)).max() < 0.05
    again = Rotation.from_euler("ZYX", smooth)
    np.testing.assert_allclose((again.inv() * rot).magnitude(), 0.0, atol=1e-9)


def test_a_spinning_root_keeps_its_heading_continuous(op3: RobotConfig) -> None:
    """Two turns about the vertical with a little tilt (a pirouette): the root's heading is
    its first channel, unwrapped past 360°, and no channel steps more than the rotation does."""
    n = 200
    heading = np.linspace(0.0, 4.0 * np.pi, n)
    tilt = 0.1 * np.sin(np.linspace(0.0, 6.0 * np.pi, n))
    rot = Rotation.from_euler("ZYX", np.column_stack([heading, tilt, 0.5 * tilt]))  # world, z up
    root_quat = np.roll(rot.as_quat(), 1, axis=1)  # scipy's x-y-z-w → w-x-y-z
    traj = RobotTrajectory(
        op3.joint_names, np.tile(op3.init_pose, (n, 1)), 50.0, np.zeros((n, 3)), root_quat
    )
    clip = robot_bvh_clip(op3, traj)
    assert clip.channels[0][3:] == ("Yrotation", "Xrotation", "Zrotation")
    root = clip.motion[:, 3:6]
    assert np.abs(np.diff(root, axis=0)).max() < 10.0  # ≈ 3.6° of heading per frame
    assert root[-1, 0] - root[0, 0] == pytest.approx(720.0, abs=1.0)  # heading, BVH Y up
    back = Rotation.from_euler("YXZ", np.radians(root))  # intrinsic, as BVH composes it
    want = Rotation.from_matrix(WORLD_TO_BVH @ rot.as_matrix() @ WORLD_TO_BVH.T)
    np.testing.assert_allclose((back.inv() * want).magnitude(), 0.0, atol=1e-9)


@pytest.mark.parametrize("robot", ["poppy_humanoid", "op3"])
def test_a_real_clip_bvh_has_no_euler_jumps(robot: str, shared_data_dir: Path,
                                            tmp_path: Path) -> None:  # fmt: skip
    """A CMU walk and a dance with pirouettes: no channel steps 90° between frames (Poppy's
    shoulders used to flip (0, −86, 0) → (−180, −88, 180), its pelvis swung 89° at a turn),
    and every frame still puts every link where the trajectory does, turned as it is."""
    config = load_robot_config(robot)
    kin = RobotKinematics(config)
    c = robot_to_canonical_rotation(config)
    for name in ("02/02_01.bvh", "05/05_02.bvh"):
        motion = load_motion(shared_data_dir / "mocap" / name)
        step = RetargetStep(config, load_model("copy"), motion.skeleton)
        traj = convert_motion(motion, step).trajectory
        clip = read_bvh(write_robot_bvh(tmp_path / f"{robot}_{Path(name).stem}.bvh", config, traj))
        jumps = np.abs(np.diff(clip.motion[:, 3:], axis=0))
        assert jumps.max() < 30.0, (name, jumps.max())  # degrees
        assert traj.root_quat is not None
        assert traj.root_pos is not None
        links = kin.link_transforms(traj.q)  # (T, L, 4, 4) in the base link's frame
        rest = kin.link_transforms(np.zeros(config.num_joints))[:, :3, :3]
        base = quat.to_matrix(traj.root_quat)
        world_pos = np.einsum("tij,tlj->tli", base, links[..., :3, 3]) + traj.root_pos[:, None]
        # A link's BVH rotation: its world rotation in BVH axes, relative to its rest (zero pose).
        want = (WORLD_TO_BVH @ base)[:, None] @ links[..., :3, :3] @ np.swapaxes(c @ rest, -1, -2)
        pos, rot = clip.global_transforms()
        order = [clip.names.index(n) for n in kin.link_names]
        np.testing.assert_allclose(pos[:, order], world_pos @ WORLD_TO_BVH.T, atol=1e-8)
        np.testing.assert_allclose(quat.to_matrix(rot[:, order]), want, atol=1e-8)
