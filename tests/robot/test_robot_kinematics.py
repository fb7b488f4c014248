"""Robot FK (robot_retarget.robot.kinematics) against an independent FK of the URDF files.

The reference parses the URDF with xml.etree and composes 4×4 transforms with scipy's Rotation
(URDF rpy = extrinsic x-y-z); it shares no code with robot_retarget.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from scipy.spatial.transform import Rotation

from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics

FloatArray = npt.NDArray[np.float64]


def _floats(text: str | None, default: str) -> FloatArray:
    return np.array([float(v) for v in (text or default).split()])


def _transform(xyz: FloatArray, rot: FloatArray) -> FloatArray:
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = xyz
    return t


def urdf_link_transforms(urdf: Path, q_by_joint: dict[str, float]) -> dict[str, FloatArray]:
    """Pose (4×4) of every URDF link in the URDF root link's frame."""
    root = ET.parse(urdf).getroot()
    joints = root.findall("joint")
    children = {j.find("child").get("link") for j in joints}  # type: ignore[union-attr]
    links = [link.get("name") for link in root.findall("link")]
    (base,) = [n for n in links if n not in children]
    poses: dict[str, FloatArray] = {str(base): np.eye(4)}
    pending = list(joints)
    while pending:
        progress = False
        for j in list(pending):
            parent = j.find("parent").get("link")  # type: ignore[union-attr]
            child = j.find("child").get("link")  # type: ignore[union-attr]
            if parent not in poses:
                continue
            origin = j.find("origin")
            xyz = _floats(None if origin is None else origin.get("xyz"), "0 0 0")
            rpy = _floats(None if origin is None else origin.get("rpy"), "0 0 0")
            t = poses[str(parent)] @ _transform(xyz, Rotation.from_euler("xyz", rpy).as_matrix())
            if j.get("type") in ("revolute", "continuous"):
                axis_el = j.find("axis")
                axis = _floats(None if axis_el is None else axis_el.get("xyz"), "1 0 0")
                angle = q_by_joint[str(j.get("name"))]
                rot = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
                t = t @ _transform(np.zeros(3), rot)
            poses[str(child)] = t
            pending.remove(j)
            progress = True
        assert progress, "URDF joints do not form a tree"
    return poses


def _check_against_urdf(config: RobotConfig, urdf: Path, seed: int) -> None:
    kin = RobotKinematics(config)
    rng = np.random.default_rng(seed)
    poses = rng.uniform(config.lower, config.upper, size=(12, config.num_joints))
    names = set(kin.frame_names)
    for q in poses:
        ref = urdf_link_transforms(urdf, dict(zip(config.joint_names, q, strict=True)))
        # Express the reference in our root link's frame (the URDF may put world/base above it).
        to_root = np.linalg.inv(ref[config.root_link])
        compared = 0
        ours_pos = kin.frame_positions(q)
        ours_rot = kin.frame_rotations(q)
        for link, t in ref.items():
            local = to_root @ t
            if link not in names:
                # Only links rigidly at the root (e.g. a URDF "world"/"base") may be absent.
                np.testing.assert_allclose(local, np.eye(4), atol=1e-12, err_msg=link)
                continue
            i = kin.frame_index(link)
            np.testing.assert_allclose(ours_pos[i], local[:3, 3], atol=1e-9, rtol=0, err_msg=link)
            np.testing.assert_allclose(ours_rot[i], local[:3, :3], atol=1e-9, rtol=0, err_msg=link)
            compared += 1
        assert compared >= config.num_joints + 1


def test_op3_fk_matches_urdf(op3: RobotConfig, op3_urdf: Path) -> None:
    _check_against_urdf(op3, op3_urdf, seed=3)


def test_poppy_fk_matches_urdf(poppy: RobotConfig, poppy_urdf: Path) -> None:
    _check_against_urdf(poppy, poppy_urdf, seed=4)


def test_op3_covers_every_urdf_link(op3: RobotConfig, op3_urdf: Path) -> None:
    links = {link.get("name") for link in ET.parse(op3_urdf).getroot().findall("link")}
    names = set(RobotKinematics(op3).frame_names)
    assert len(links) == 23
    assert links <= names


def test_batched_equals_single(op3: RobotConfig) -> None:
    kin = RobotKinematics(op3)
    q = np.random.default_rng(0).uniform(op3.lower, op3.upper, size=(2, 3, op3.num_joints))
    batched = kin.frame_positions(q)
    assert batched.shape == (2, 3, len(kin.frame_names), 3)
    for a in range(2):
        for b in range(3):
            np.testing.assert_array_equal(batched[a, b], kin.frame_positions(q[a, b]))


def test_frame_subset_and_order(op3: RobotConfig) -> None:
    kin = RobotKinematics(op3)
    q = op3.init_pose
    full = kin.frame_positions(q)
    sub = kin.frame_positions(q, ["l_hand", "body_link", "r_sole"])
    np.testing.assert_array_equal(sub[0], full[kin.frame_index("l_hand")])
    np.testing.assert_array_equal(sub[1], np.zeros(3))
    np.testing.assert_array_equal(sub[2], full[kin.frame_index("r_sole")])
    with pytest.raises(KeyError, match="no frame 'nose'"):
        kin.frame_positions(q, ["nose"])


def test_root_transform_moves_everything(op3: RobotConfig) -> None:
    kin = RobotKinematics(op3)
    q = np.random.default_rng(1).uniform(op3.lower, op3.upper, size=(4, op3.num_joints))
    root = np.tile(np.eye(4), (4, 1, 1))
    root[:, :3, :3] = Rotation.from_rotvec(np.random.default_rng(2).normal(size=(4, 3))).as_matrix()
    root[:, :3, 3] = [0.1, -0.2, 0.3]
    moved = kin.frame_transforms(q, root_transform=root)
    expected = root[:, None] @ kin.frame_transforms(q)
    np.testing.assert_allclose(moved, expected, atol=1e-12)
    links = kin.link_transforms(q, root_transform=root)
    np.testing.assert_allclose(links, moved[:, : len(kin.link_names)], atol=1e-15)


def test_zero_pose_geometry(op3: RobotConfig) -> None:
    """Known OP3 numbers: 0.11015 m thigh, 0.110 m shin, ROBOTIS hand point 0.15 m."""
    kin = RobotKinematics(op3)
    p = dict(zip(kin.frame_names, kin.frame_positions(np.zeros(op3.num_joints)), strict=True))
    assert np.linalg.norm(p["l_knee_center"] - p["l_hip_center"]) == pytest.approx(0.11015)
    assert np.linalg.norm(p["l_ankle_center"] - p["l_knee_center"]) == pytest.approx(0.110)
    assert np.linalg.norm(p["l_hand"] - p["l_el_link"]) == pytest.approx(0.15)
    assert p["l_sole"][2] == pytest.approx(-0.0285 - 0.11015 - 0.110 - 0.0305)


def test_wrong_joint_count_is_rejected(op3: RobotConfig) -> None:
    with pytest.raises(ValueError, match="last axis of 20"):
        RobotKinematics(op3).frame_positions(np.zeros(19))


def test_a_joint_carries_the_frames_below_it(op3: RobotConfig) -> None:
    kin = RobotKinematics(op3)
    carried = kin.carried_frames(["l_sole", "r_sole", "body_link"])
    names = [j.name for j in op3.joints]
    assert carried[names.index("l_knee")].tolist() == [True, False, False]
    assert carried[names.index("r_ank_roll")].tolist() == [False, True, False]
    assert not carried[:, 2].any()  # the root link moves with no joint
    assert kin.carried_frames().shape == (op3.num_joints, len(kin.frame_names))
