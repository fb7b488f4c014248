"""TreeKinematics: the live steps' pointer-jumping forward kinematics against the skeleton's."""

from __future__ import annotations

import numpy as np

from robot_retarget.geometry import quaternion as quat
from robot_retarget.runtime.frame import TreeKinematics, matrices
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, default_canonical_skeleton
from robot_retarget.skeleton.skeleton import forward_kinematics


def test_one_frame_and_a_batch_agree_with_forward_kinematics() -> None:
    skeleton = default_canonical_skeleton()
    local = quat.normalize(np.random.default_rng(0).normal(size=(5, 22, 4)))
    want_pos, want_glob = forward_kinematics(skeleton, local)
    kin = TreeKinematics(CANONICAL_PARENTS)
    rot = matrices(local.reshape(-1, 4)).reshape(5, 22, 3, 3)
    glob, pos = kin.pose(rot, skeleton.offsets)
    np.testing.assert_allclose(pos, want_pos, atol=1e-12)
    np.testing.assert_allclose(glob, quat.to_matrix(want_glob), atol=1e-12)
    for t in range(5):
        np.testing.assert_allclose(kin.positions(rot[t], skeleton.offsets), want_pos[t], atol=1e-12)
