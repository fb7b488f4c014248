"""Bone geometry: the canonical → robot frame map, rest axes, parents, alignments."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robot_retarget.errors import ConfigError
from robot_retarget.optimize.bone_model import body_to_root, canonical_to_root
from robot_retarget.optimize.formulation import RobotProblem
from robot_retarget.robot.config import BoneConfig, RobotConfig


def test_canonical_axes_map_to_robot_axes(op3: RobotConfig) -> None:
    m0 = canonical_to_root(op3)
    # Canonical left (+X), up (+Y), facing (+Z) → OP3 body_link +y, +z, +x.
    np.testing.assert_allclose(m0 @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(m0 @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(m0 @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    assert np.linalg.det(m0) == pytest.approx(1.0)


def test_forward_parallel_to_up_is_a_config_error(op3: RobotConfig) -> None:
    bad = dataclasses.replace(op3, forward_axis=(0.0, 0.0, 2.0))
    with pytest.raises(ConfigError) as err:
        body_to_root(bad)
    assert err.value.key == "forward_axis"


def test_op3_bones(op3: RobotConfig) -> None:
    prob = RobotProblem(op3)
    names = [b.canonical for b in prob.bones]
    by_name = dict(zip(names, prob.bones, strict=True))
    np.testing.assert_allclose(by_name["LeftArm"].rest_axis, [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(by_name["RightLeg"].rest_axis, [0.0, 0.0, -1.0], atol=1e-12)
    # Parents for the twist: forearm → upper arm, upper arm → torso, thigh → root.
    assert names[by_name["LeftForeArm"].parent] == "LeftArm"
    assert names[by_name["LeftArm"].parent] == "Hips"
    assert by_name["LeftUpLeg"].parent == -1
    # OP3's zero pose is a T-pose: limb rotations relative to it are (almost) the identity
    # there; head and feet differ by the shortest arc from the canonical rest direction.
    q0 = np.zeros(op3.num_joints)
    twists = np.asarray(prob.twists_function(q0)).ravel()
    np.testing.assert_allclose(twists, 0.0, atol=0.01)
    normals = np.asarray(prob.normals_function(q0)).T
    limbs = [i for i, n in enumerate(names) if n.endswith(("Arm", "Leg", "UpLeg"))]
    rest = np.array([prob.bones[i].rest_normal for i in limbs])
    assert np.all(np.sum(normals[limbs] * rest, axis=1) > np.cos(np.radians(1.0)))


def test_bone_to_the_root_joint_is_rejected(op3: RobotConfig) -> None:
    bad = dataclasses.replace(op3, bones=(BoneConfig("Spine", "Hips", "body_link", "l_el_link"),))
    with pytest.raises(ConfigError, match="ends at the root"):
        RobotProblem(bad)
