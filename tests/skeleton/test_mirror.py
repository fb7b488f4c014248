"""Mirroring canonical motion: FK of the mirrored motion is the mirrored FK."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, default_canonical_skeleton
from robot_retarget.skeleton.mirror import (
    JOINT_MIRROR,
    mirror_offsets,
    mirror_points,
    mirror_rotations,
)
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics


def _random_pose(seed: int, frames: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(frames, len(CANONICAL_JOINTS), 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    root = rng.normal(size=(frames, 3))
    # Asymmetric bone lengths, so a mirror that forgot to swap the sides would show.
    offsets = default_canonical_skeleton().offsets * rng.uniform(
        0.7, 1.3, (len(CANONICAL_JOINTS), 1)
    )
    return q, root, offsets


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_fk_of_the_mirrored_motion_is_the_mirrored_fk(seed: int) -> None:
    q, root, offsets = _random_pose(seed)
    base = Skeleton(CANONICAL_JOINTS, default_canonical_skeleton().parents, offsets)
    mirrored = Skeleton(CANONICAL_JOINTS, base.parents, mirror_offsets(offsets))
    pos, glob = forward_kinematics(base, q, root)
    pos_m, glob_m = forward_kinematics(mirrored, mirror_rotations(q), mirror_points(root))
    np.testing.assert_allclose(pos_m, mirror_points(pos[:, JOINT_MIRROR]), atol=1e-12)
    # Global rotations mirror the same way as local ones.
    dots = np.abs(np.sum(glob_m * mirror_rotations(glob), axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-12)


def test_mirroring_twice_is_the_identity_and_the_sides_swap() -> None:
    q, _root, offsets = _random_pose(1)
    np.testing.assert_array_equal(mirror_rotations(mirror_rotations(q)), q)
    np.testing.assert_array_equal(mirror_offsets(mirror_offsets(offsets)), offsets)
    left, right = CANONICAL_JOINTS.index("LeftForeArm"), CANONICAL_JOINTS.index("RightForeArm")
    assert JOINT_MIRROR[left] == right
    assert JOINT_MIRROR[right] == left
    assert JOINT_MIRROR[0] == 0
    np.testing.assert_allclose(quat.normalize(mirror_rotations(q)), mirror_rotations(q))
