"""Aligning a motion to the canonical T-pose keeps every joint where it was."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.rest_pose import TPOSE_BONE_DIRECTIONS, align_to_tpose
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics, local_from_global


def _bent_rest_skeleton(seed: int) -> Skeleton:
    """The default T-pose with every bone tilted at random: an A-pose / splayed-leg rest."""
    rng = np.random.default_rng(seed)
    skel = default_canonical_skeleton()
    tilt = quat.from_rotation_vector(rng.normal(scale=0.35, size=(skel.num_joints, 3)))
    return skel.with_offsets(quat.rotate(tilt, skel.offsets))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_alignment_keeps_joint_positions(seed: int) -> None:
    skel = _bent_rest_skeleton(seed)
    rng = np.random.default_rng(seed + 1)
    local = quat.normalize(rng.normal(size=(5, skel.num_joints, 4)))
    pos, glob = forward_kinematics(skel, local)
    aligned, glob2 = align_to_tpose(skel, glob)
    pos2, _ = forward_kinematics(aligned, local_from_global(aligned, glob2))
    np.testing.assert_allclose(pos2, pos, atol=1e-12)
    np.testing.assert_allclose(aligned.bone_lengths(), skel.bone_lengths(), atol=1e-12)


def test_aligned_rest_pose_is_the_tpose() -> None:
    aligned, _ = align_to_tpose(_bent_rest_skeleton(3), quat.identity((1, 22)))
    for joint, direction in TPOSE_BONE_DIRECTIONS.items():
        offset = aligned.offsets[aligned.index(joint)]
        np.testing.assert_allclose(offset / np.linalg.norm(offset), direction, atol=1e-12)
    toe = aligned.offsets[aligned.index("LeftToeBase")]
    assert toe[0] == pytest.approx(0.0, abs=1e-12)  # toe-out removed
    assert toe[2] > 0.0  # still pointing forward


def test_tpose_skeleton_is_left_unchanged() -> None:
    skel = default_canonical_skeleton()
    glob = quat.normalize(np.random.default_rng(0).normal(size=(4, 22, 4)))
    aligned, glob2 = align_to_tpose(skel, glob)
    np.testing.assert_allclose(aligned.offsets, skel.offsets, atol=1e-15)
    np.testing.assert_allclose(glob2, glob, atol=1e-15)


def test_zero_length_bones_are_left_alone() -> None:
    skel = default_canonical_skeleton()
    offsets = skel.offsets.copy()
    offsets[skel.index("Spine2")] = 0.0  # a synthesised zero-length spine joint (DAZ)
    zero = skel.with_offsets(offsets)
    aligned, _ = align_to_tpose(zero, quat.identity((1, 22)))
    np.testing.assert_array_equal(aligned.offsets[skel.index("Spine2")], 0.0)
