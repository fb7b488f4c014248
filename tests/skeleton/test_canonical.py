"""The canonical 22-joint human: joint set, tree, symmetry and the default T-pose."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.skeleton import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    REQUIRED_JOINTS,
    Joint,
    Skeleton,
)
from robot_retarget.skeleton.canonical import END_EFFECTORS, MIRROR_PAIRS


def test_joint_set_and_order() -> None:
    assert len(CANONICAL_JOINTS) == 22
    assert CANONICAL_JOINTS[0] == "Hips"
    assert [Joint[n].value for n in CANONICAL_JOINTS] == list(range(22))
    assert CANONICAL_PARENTS[0] == -1
    assert all(0 <= p < i for i, p in enumerate(CANONICAL_PARENTS) if i > 0)


@pytest.mark.parametrize(
    ("child", "parent"),
    [("Head", "Neck"), ("LeftArm", "LeftShoulder"), ("RightShoulder", "Spine2"),
     ("LeftUpLeg", "Hips"), ("RightToeBase", "RightFoot")],
)  # fmt: skip
def test_parents(child: str, parent: str) -> None:
    assert CANONICAL_PARENTS[Joint[child]] == Joint[parent]


def test_required_effectors_and_mirror_pairs_name_real_joints() -> None:
    assert set(REQUIRED_JOINTS) <= set(CANONICAL_JOINTS)
    assert set(END_EFFECTORS) <= set(CANONICAL_JOINTS)
    assert len(MIRROR_PAIRS) == 8
    for left, right in MIRROR_PAIRS:
        assert left.startswith("Left")
        assert right == "Right" + left[4:]
        assert right in CANONICAL_JOINTS


def test_default_skeleton_is_a_mirror_symmetric_t_pose(canonical: Skeleton) -> None:
    assert canonical.names == CANONICAL_JOINTS
    assert canonical.parents == CANONICAL_PARENTS
    rest = canonical.rest_positions()
    for left, right in MIRROR_PAIRS:
        np.testing.assert_allclose(rest[Joint[right]], rest[Joint[left]] * [-1.0, 1.0, 1.0])
    # Y up, left = +X, facing +Z, arms horizontal.
    assert rest[Joint.Head, 1] > rest[Joint.Hips, 1] > rest[Joint.LeftFoot, 1]
    assert rest[Joint.LeftHand, 0] > 0.5
    assert rest[Joint.LeftToeBase, 2] > 0.0
    assert rest[Joint.LeftHand, 1] == pytest.approx(rest[Joint.LeftArm, 1])


def test_default_skeleton_is_adult_sized(canonical: Skeleton) -> None:
    rest = canonical.rest_positions()
    head_to_toe = rest[Joint.Head, 1] - rest[Joint.LeftToeBase, 1]
    arm_span = rest[Joint.LeftHand, 0] - rest[Joint.RightHand, 0]
    assert 1.3 < head_to_toe < 1.8  # head joint, not the top of the skull
    assert 1.3 < arm_span < 1.9
