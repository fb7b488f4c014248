from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint, default_canonical_skeleton
from robot_retarget.skeleton.skeleton import forward_kinematics
from robot_retarget.sources.from_positions import PositionsToRotations

SKELETON = default_canonical_skeleton()
SOLVER = PositionsToRotations(SKELETON)
_rotvecs = arrays(np.float64, (22, 3), elements=st.floats(-1.2, 1.2))
_roots = arrays(np.float64, (3,), elements=st.floats(-2.0, 2.0))


@settings(max_examples=30)
@given(_rotvecs, _roots)
def test_positions_are_reproduced(rotvecs: np.ndarray, root: np.ndarray) -> None:
    local = quat.from_rotation_vector(rotvecs)
    pos, _ = forward_kinematics(SKELETON, local, root)
    solved, solved_root = SOLVER.solve(pos)
    again, _ = forward_kinematics(SKELETON, solved, solved_root)
    np.testing.assert_allclose(again, pos, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(solved, axis=-1), 1.0, atol=1e-12)


@settings(max_examples=20)
@given(_rotvecs)
def test_single_child_joints_get_no_twist(rotvecs: np.ndarray) -> None:
    pos, _ = forward_kinematics(SKELETON, quat.from_rotation_vector(rotvecs))
    solved, _ = SOLVER.solve(pos)
    children: dict[int, list[int]] = {}
    for j, p in enumerate(CANONICAL_PARENTS):
        if p >= 0:
            children.setdefault(p, []).append(j)
    for j, kids in children.items():
        if len(kids) == 1 and j not in (0, 3):  # Hips and Spine2 use triads
            twist = quat.twist_angle(solved[j], SKELETON.offsets[kids[0]])
            assert abs(float(twist)) < 1e-9


def test_rest_pose_gives_identity_rotations() -> None:
    solved, root = SOLVER.solve(SKELETON.rest_positions())
    np.testing.assert_allclose(np.abs(solved[:, 0]), 1.0, atol=1e-12)
    np.testing.assert_allclose(root, 0.0)


def test_degenerate_positions_do_not_fail() -> None:
    solved, _ = SOLVER.solve(np.zeros((22, 3)))
    assert np.all(np.isfinite(solved))


@settings(max_examples=30)
@given(
    yaw=st.floats(-np.pi, np.pi), rotvecs=arrays(np.float64, (22, 3), elements=st.floats(-0.8, 0.8))
)
def test_a_spine_joint_at_the_hips_still_turns_the_hips(yaw: float, rotvecs: np.ndarray) -> None:
    """CMU MotionBuilder skeletons put Spine on the Hips (a zero-length bone): the Hips'
    rotation must come from the next spine joint up, not be left at identity (a performer
    facing sideways came out up to 90° off)."""
    base = default_canonical_skeleton()
    offsets = base.offsets.copy()
    offsets[Joint.Spine1] += offsets[Joint.Spine]  # Spine moves onto the Hips; the rest stays
    offsets[Joint.Spine] = 0.0
    skeleton = type(base)(base.names, base.parents, offsets)
    quats = quat.from_rotation_vector(rotvecs)
    quats[0] = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), yaw)  # the performer turned
    quats[Joint.Spine] = quat.identity(())  # a zero-length bone's own turn cannot be seen
    pos = forward_kinematics(skeleton, quats[None], np.zeros((1, 3)))[0][0]
    local, root = PositionsToRotations(skeleton).solve(pos)
    again = forward_kinematics(skeleton, local[None], root[None])[0][0]
    np.testing.assert_allclose(again, pos, atol=1e-6)


@settings(max_examples=40)
@given(
    arrays(np.float64, (22, 3), elements=st.floats(-3.1, 3.1)),
    st.sampled_from([1.0, 1e-3]),
)
def test_the_compiled_solve_equals_the_numpy_solve(rotvecs: np.ndarray, scale: float) -> None:
    """Wild poses, and a skeleton a thousand times smaller (bones near the ε tests)."""
    skeleton = SKELETON if scale == 1.0 else SKELETON.scaled(scale)
    solver = SOLVER if scale == 1.0 else PositionsToRotations(skeleton)
    pos, _ = forward_kinematics(skeleton, quat.from_rotation_vector(rotvecs))
    compiled, root = solver.solve(pos)
    reference, ref_root = solver._numpy_solve(pos)
    np.testing.assert_allclose(compiled, reference, atol=1e-9)
    np.testing.assert_array_equal(root, ref_root)


def test_a_folded_bone_takes_the_numpy_branches() -> None:
    """A bone pointing exactly back along its rest direction (the shortest arc's half turn)
    and a zero-length bone: the graph's margin hands both to the numpy path."""
    pos = SKELETON.rest_positions()
    arm, fore, hand = Joint.LeftArm, Joint.LeftForeArm, Joint.LeftHand
    folded = pos.copy()
    folded[hand] = pos[fore] - (pos[hand] - pos[fore])
    collapsed = pos.copy()
    collapsed[fore] = pos[arm]
    for p in (folded, collapsed):
        got, _ = SOLVER.solve(p)
        np.testing.assert_allclose(got, SOLVER._numpy_solve(p)[0], atol=1e-12)
        assert np.all(np.isfinite(got))
