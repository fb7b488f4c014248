"""The trajectory's floating base, checked with an independent URDF forward kinematics.

The robot's links are computed from a written NPZ (``root_pos`` / ``root_quat`` + ``q``) by
walking the manufacturer's URDF with scipy's rotations — none of the project's kinematics — and
the feet must stand on z = 0 (± 1 cm) whenever the performer stands, and never go below it.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot_retarget.errors import ConfigError
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.nn.inference import load_model
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.floating_base import (
    HUMAN_TO_WORLD,
    FloatingBaseError,
    floating_base,
    foot_points,
    foot_skate_m_s,
    human_foot_heights_m,
    leg_length_m,
    planted_skate_m_s,
    trajectory_feet,
)
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.skeleton.canonical import Joint

URDFS = {
    "op3": "robotis_op3/urdf/robotis_op3.expanded.urdf",
    "poppy_humanoid": "poppy_humanoid/Poppy_Humanoid.URDF",
}
CLIPS = ("02/02_01.bvh", "06/06_01.bvh", "05/05_02.bvh")  # two walks and a dance


def _floats(text: str | None) -> np.ndarray:
    return np.array([float(v) for v in (text or "0 0 0").split()])


class UrdfTree:
    """Link poses from a URDF file: world pose of the base link, then joint by joint."""

    def __init__(self, path: Path) -> None:
        root = ET.parse(path).getroot()
        self.joints: dict[str, tuple[str, str, np.ndarray, Rotation, np.ndarray, str]] = {}
        for j in root.findall("joint"):
            origin = j.find("origin")
            axis = j.find("axis")
            xyz = _floats(origin.get("xyz") if origin is not None else None)
            rpy = _floats(origin.get("rpy") if origin is not None else None)
            self.joints[str(j.get("name"))] = (
                str(j.find("parent").get("link")),  # type: ignore[union-attr]
                str(j.find("child").get("link")),  # type: ignore[union-attr]
                xyz,
                Rotation.from_euler("xyz", rpy),  # URDF rpy: fixed-axis roll, pitch, yaw
                _floats(axis.get("xyz") if axis is not None else "1 0 0"),
                str(j.get("type")),
            )

    def link_poses(
        self, base: str, base_pos: np.ndarray, base_rot: Rotation, q: dict[str, float]
    ) -> dict[str, tuple[np.ndarray, Rotation]]:
        poses = {base: (base_pos, base_rot)}
        pending = dict(self.joints)
        while pending:
            done = [n for n, j in pending.items() if j[0] in poses]
            if not done:
                break  # links not below the base (e.g. a "world" link above it)
            for name in done:
                parent, child, xyz, rot, axis, kind = pending.pop(name)
                p, r = poses[parent]
                moving = Rotation.from_rotvec(axis * q.get(name, 0.0)) if kind != "fixed" else (
                    Rotation.identity()
                )  # fmt: skip
                poses[child] = (p + r.apply(xyz), r * rot * moving)
        return poses


def _feet_world(config: RobotConfig, tree: UrdfTree, traj: RobotTrajectory) -> np.ndarray:
    """(T, F, 3) foot points (the config's sole/toe offsets on the URDF's foot links)."""
    frames = {f.name: f for f in config.frames}
    points = [frames[n] for n in foot_points(config)]
    assert traj.root_pos is not None
    assert traj.root_quat is not None
    out = np.empty((traj.num_frames, len(points), 3))
    for t in range(traj.num_frames):
        q = dict(zip(traj.joint_names, traj.q[t], strict=True))
        w, x, y, z = traj.root_quat[t]
        poses = tree.link_poses(
            config.root_link, traj.root_pos[t], Rotation.from_quat([x, y, z, w]), q
        )
        for k, f in enumerate(points):
            p, r = poses[f.parent_link]
            out[t, k] = p + r.apply(np.asarray(f.origin_xyz))
    return out


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_feet_stand_on_the_ground_by_an_independent_urdf_fk(
    robot: str, shared_data_dir: Path, tmp_path: Path
) -> None:
    config = load_robot_config(robot)
    if robot == "op3":  # the MJCF foot box's back edge: the lowest point at a heel strike
        assert {"l_heel", "r_heel"} <= set(foot_points(config))
    tree = UrdfTree(shared_data_dir / "robots" / URDFS[robot])
    model = load_model("copy")
    for clip in CLIPS:
        motion = load_motion(shared_data_dir / "mocap" / clip, max_frames=600)
        step = RetargetStep(config, model, motion.skeleton)
        traj = convert_motion(motion, step).trajectory
        read = RobotTrajectory.read(traj.write(tmp_path / f"{robot}_{Path(clip).stem}.npz"))
        feet = _feet_world(config, tree, read)
        lowest = feet[:, :, 2].min(axis=1)
        assert lowest.min() > -0.01, (clip, lowest.min())  # never below the ground
        # Where the performer stands (an ankle or a toe at its lowest, as in a heel strike or
        # a toe-off), so does the robot.
        human = motion.resample(config.control_rate_hz)
        pos = human.positions()[: read.num_frames]
        joints = [Joint.LeftFoot, Joint.RightFoot, Joint.LeftToeBase, Joint.RightToeBase]
        y = pos[:, joints, 1]
        stance = (y - y.min(axis=0) < 0.015).any(axis=1)
        assert stance.sum() > 20, clip
        np.testing.assert_allclose(lowest[stance], 0.0, atol=0.01)


def test_base_pose_is_z_up_and_follows_the_pelvis() -> None:
    """A standing performer turned to face their left: the robot's base faces +y (left), z up,
    and its height puts the lowest foot point exactly on the ground."""
    config = load_robot_config("op3")
    motion = demo_motion(fps=25.0).frames(0, 5)
    quarter = Rotation.from_euler("y", 90, degrees=True).as_quat()  # about the human's up (Y)
    local = motion.local_quats.copy()
    local[:, 0] = np.roll(quarter, 1)  # w-x-y-z, pelvis upright, turned left
    turned = HumanMotion(**{**motion.__dict__, "local_quats": local})
    base = floating_base(config, turned, np.tile(config.init_pose, (5, 1)))
    rot = Rotation.from_quat(np.roll(base.root_quat[0], -1))
    forward = rot.apply(np.asarray(config.forward_axis, dtype=float))
    up = rot.apply(np.asarray(config.up_axis, dtype=float))
    np.testing.assert_allclose(forward, [0.0, 1.0, 0.0], atol=1e-9)  # human left → world +y
    np.testing.assert_allclose(up, [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(base.feet[:, :, 2].min(axis=1), 0.0, atol=1e-9)
    np.testing.assert_allclose(base.root_pos[0, :2], 0.0, atol=1e-12)  # origin under the pelvis
    np.testing.assert_allclose(HUMAN_TO_WORLD @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])


def test_pinning_stops_a_stance_foot_sliding(shared_data_dir: Path) -> None:
    config = load_robot_config("op3")
    motion = load_motion(shared_data_dir / "mocap" / "05" / "05_02.bvh", max_frames=600)
    traj = convert_motion(motion, RetargetStep(config, load_model("copy"), motion.skeleton))
    human = motion.resample(config.control_rate_hz)
    free = floating_base(config, human, traj.trajectory.q, pin_feet=False)
    pinned = floating_base(config, human, traj.trajectory.q)
    rate = config.control_rate_hz
    assert foot_skate_m_s(pinned.feet, rate) < 0.5 * foot_skate_m_s(free.feet, rate)
    # What a tool that loads the base pose sees (eval-robot's robot foot skate): its feet.
    q = traj.trajectory.q
    seen = trajectory_feet(config, q, pinned.root_pos, pinned.root_quat)
    np.testing.assert_allclose(seen, pinned.feet, atol=1e-9)
    assert not np.allclose(seen, free.feet, atol=1e-3)


def test_a_heel_strike_is_on_the_ground() -> None:
    """Ankles stand higher than toes: a foot on its heel (ankle at its standing height, toe
    raised) is on the ground, so is one on its toes; a foot with both raised is not."""
    stand = np.zeros((4, 22, 3))
    stand[:, [Joint.LeftFoot, Joint.RightFoot], 1] = 0.08
    stand[:, [Joint.LeftToeBase, Joint.RightToeBase], 1] = 0.02
    stand[1, [Joint.RightFoot, Joint.LeftToeBase, Joint.RightToeBase], 1] += 0.3  # heel strike
    stand[2, [Joint.LeftFoot, Joint.RightFoot, Joint.RightToeBase], 1] += 0.3  # on the toes
    stand[3, [Joint.LeftFoot, Joint.RightFoot, Joint.LeftToeBase, Joint.RightToeBase], 1] += 0.1
    heights = human_foot_heights_m(np.concatenate([np.tile(stand[:1], (60, 1, 1)), stand]))
    np.testing.assert_allclose(heights.min(axis=1)[-4:], [0.0, 0.0, 0.0, 0.1], atol=1e-12)


def test_a_jump_leaves_the_ground(shared_data_dir: Path) -> None:
    """CMU 02_04 (jump, balance): the robot's feet leave the ground only while the performer
    is in the air, by the performer's height scaled to the robot."""
    config = load_robot_config("poppy_humanoid")
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_04.bvh").resample(50.0)
    q = np.tile(config.init_pose, (motion.num_frames, 1))
    base = floating_base(config, motion, q)
    lowest = base.feet[:, :, 2].min(axis=1)
    ratio = leg_length_m(robot_canonical_skeleton(config)) / leg_length_m(motion.skeleton)
    airborne = human_foot_heights_m(motion.positions()).min(axis=1)
    assert airborne.max() > 0.15  # the performer's jump, metres
    np.testing.assert_allclose(lowest, ratio * airborne, atol=1e-9)


def test_bad_input_is_refused() -> None:
    config = load_robot_config("op3")
    motion = demo_motion(fps=25.0).frames(0, 5)
    with pytest.raises(FloatingBaseError, match="q must be") as err:
        floating_base(config, motion, np.zeros((4, config.num_joints)))
    assert err.value.got == (4, config.num_joints)
    footless = dataclasses.replace(
        config, bones=tuple(b for b in config.bones if "Foot" not in b.canonical_end
                            and "Toe" not in b.canonical_end)
    )  # fmt: skip
    with pytest.raises(ConfigError, match="no foot bones"):
        foot_points(footless)


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_the_base_walks_on_steadily_where_the_performer_does(
    shared_data_dir: Path, robot: str
) -> None:
    """CMU 02_01 walks straight ahead. OP3's swing foot skims the floor; the base must not be
    pinned to it (it went 0.32 m backwards for 0.76 m forward), and the feet the performer
    stands on stay put."""
    config = load_robot_config(robot)
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh")
    traj = convert_motion(motion, RetargetStep(config, load_model("default"), motion.skeleton))
    rate = config.control_rate_hz
    human = motion.resample(rate)
    base = floating_base(config, human, traj.trajectory.q)
    xy = base.root_pos[:, :2]
    ahead = (xy[-1] - xy[0]) / np.linalg.norm(xy[-1] - xy[0])
    along = np.diff(xy, axis=0) @ ahead
    assert -along[along < 0].sum() < 0.02 * along[along > 0].sum()  # OP3 was 42 %
    assert along.min() * rate > -0.3  # m/s; OP3 was −1.27
    # Feet the performer stands on, on the floor in consecutive frames, are held.
    heights = human_foot_heights_m(human.positions())
    sides = [0 if name.startswith("l") else 1 for name in base.foot_frames]
    planted = np.stack([heights[:, [0, 2]].min(1), heights[:, [1, 3]].min(1)], 1) < 0.03

    def held_speed(feet: np.ndarray) -> float:
        held = (feet[:, :, 2] <= 0.01) & planted[:, sides]
        both = held[1:] & held[:-1]
        return float((np.linalg.norm(np.diff(feet[:, :, :2], axis=0), axis=-1)[both]).mean())

    free = floating_base(config, human, traj.trajectory.q, pin_feet=False)
    assert held_speed(base.feet) < 0.7 * held_speed(free.feet)  # OP3: 0.064 vs 0.123 m/s


def test_skate_under_planted_feet_counts_only_the_feet_the_performer_stands_on() -> None:
    # Two feet on the floor: one still, one moving 1 cm per frame (a swing foot skimming it).
    t = np.arange(10, dtype=float)
    feet = np.zeros((10, 2, 3))
    feet[:, 1, 0] = 0.01 * t
    planted = np.zeros((10, 2), dtype=bool)
    planted[:, 0] = True
    assert foot_skate_m_s(feet, 100.0) == pytest.approx(0.5)  # (0 + 1 m/s) / 2
    assert planted_skate_m_s(feet, 100.0, planted) == 0.0
    planted[:, 1] = True
    assert planted_skate_m_s(feet, 100.0, planted) == pytest.approx(0.5)
    # Nothing planted on the floor: nothing measured, not a perfect score.
    assert planted_skate_m_s(feet, 100.0, np.zeros((10, 2), dtype=bool)) is None
    feet[:, :, 2] = 0.05
    assert planted_skate_m_s(feet, 100.0, planted) is None
