"""Skeleton validation, rest pose and numpy forward kinematics."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton import Skeleton, forward_kinematics, local_from_global

FloatArray = npt.NDArray[np.float64]

EXAMPLES = settings(max_examples=100, deadline=None)


@st.composite
def skeletons(draw: st.DrawFn, max_joints: int = 12) -> Skeleton:
    """Random trees in topological order with random offsets (zero-length bones included)."""
    n = draw(st.integers(1, max_joints))
    parents = [-1] + [draw(st.integers(0, i - 1)) for i in range(1, n)]
    offsets = draw(arrays(np.float64, (n, 3), elements=st.floats(-2.0, 2.0)))
    return Skeleton(tuple(f"j{i}" for i in range(n)), tuple(parents), offsets)


@st.composite
def posed(draw: st.DrawFn, frames: int = 3) -> tuple[Skeleton, FloatArray, FloatArray]:
    """A random skeleton with random unit local rotations (frames, J, 4) and root positions."""
    skel = draw(skeletons())
    raw = draw(
        arrays(np.float64, (frames, skel.num_joints, 4), elements=st.floats(-1.0, 1.0)).filter(
            lambda q: bool(np.all(np.linalg.norm(q, axis=-1) > 0.1))
        )
    )
    root = draw(arrays(np.float64, (frames, 3), elements=st.floats(-5.0, 5.0)))
    return skel, quat.normalize(raw), root


def fk_by_matrices(skel: Skeleton, local: FloatArray, root: FloatArray) -> FloatArray:
    """Independent reference: chain 4×4 homogeneous transforms, one joint at a time."""
    world: list[FloatArray] = []
    for i, p in enumerate(skel.parents):
        t = np.eye(4)
        t[:3, :3] = quat.to_matrix(local[i])
        t[:3, 3] = root if p < 0 else skel.offsets[i]
        world.append(t if p < 0 else world[p] @ t)
    return np.array([w[:3, 3] for w in world])


# --- validation ---------------------------------------------------------------------------


def test_valid_skeleton_keeps_its_fields(chain: Skeleton) -> None:
    assert chain.num_joints == 3
    assert chain.parents == (-1, 0, 1)
    assert chain.names == ("root", "a", "b")
    assert chain.offsets.dtype == np.float64


@pytest.mark.parametrize(
    ("names", "parents", "offsets", "match"),
    [
        ((), (), np.zeros((0, 3)), "at least one joint"),
        (("a", "b"), (-1,), np.zeros((2, 3)), "sizes disagree"),
        (("a", "b"), (-1, 0), np.zeros((3, 3)), "sizes disagree"),
        (("a", "b"), (-1, 0), np.zeros((2, 2)), "sizes disagree"),
        (("a", "b"), (0, -1), np.zeros((2, 3)), "must be the root"),
        (("a", "b", "c"), (-1, 2, 1), np.zeros((3, 3)), "parents must come first"),
        (("a", "b", "c"), (-1, 0, 2), np.zeros((3, 3)), "parents must come first"),
        (("a", "b", "c"), (-1, -1, 0), np.zeros((3, 3)), "parents must come first"),
        (("a", "b", "a"), (-1, 0, 1), np.zeros((3, 3)), "duplicate joint names: \\['a'\\]"),
        (("a", "b"), (-1, 0), np.array([[0.0, 0, 0], [np.nan, 0, 0]]), "finite"),
        (("a", "b"), (-1, 0), np.array([[0.0, 0, 0], [np.inf, 0, 0]]), "finite"),
    ],
)
def test_invalid_skeletons_raise(
    names: tuple[str, ...], parents: tuple[int, ...], offsets: FloatArray, match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        Skeleton(names, parents, offsets)


def test_offsets_are_an_own_read_only_copy() -> None:
    offsets = np.array([[0.0, 0, 0], [1, 0, 0]])
    skel = Skeleton(("a", "b"), (-1, 0), offsets)
    offsets[1, 0] = 5.0
    assert skel.offsets[1, 0] == 1.0
    with pytest.raises(ValueError, match="read-only"):
        skel.offsets[1, 0] = 2.0


def test_from_parent_names_and_lookups(chain: Skeleton) -> None:
    skel = Skeleton.from_parent_names(["root", "a", "b"], [None, "root", "a"], chain.offsets)
    assert skel.parents == chain.parents
    assert skel.index("b") == 2
    assert skel.children(0) == (1,)
    assert skel.children(2) == ()
    with pytest.raises(KeyError, match="joints are"):
        skel.index("nope")


def test_bone_lengths_scaled_and_with_offsets(chain: Skeleton) -> None:
    np.testing.assert_array_equal(chain.bone_lengths(), [0.0, 1.0, 1.0])
    np.testing.assert_array_equal(chain.scaled(0.5).bone_lengths(), [0.0, 0.5, 0.5])
    moved = chain.with_offsets(np.ones((3, 3)))
    assert moved.names == chain.names
    np.testing.assert_array_equal(moved.offsets, np.ones((3, 3)))
    with pytest.raises(ValueError, match="sizes disagree"):
        chain.with_offsets(np.ones((2, 3)))


# --- rest pose and FK ---------------------------------------------------------------------


def test_rest_positions_of_a_chain(chain: Skeleton) -> None:
    np.testing.assert_array_equal(chain.rest_positions(), [[0, 0, 0], [1, 0, 0], [2, 0, 0]])


@EXAMPLES
@given(skeletons())
def test_rest_positions_sum_offsets_along_the_path_to_the_root(skel: Skeleton) -> None:
    rest = skel.rest_positions()
    for i in range(skel.num_joints):
        total, j = np.zeros(3), i
        while j > 0:
            total += skel.offsets[j]
            j = skel.parents[j]
        np.testing.assert_allclose(rest[i], total, atol=1e-12)


@EXAMPLES
@given(skeletons(), arrays(np.float64, 3, elements=st.floats(-10.0, 10.0)))
def test_fk_at_identity_is_the_rest_pose(skel: Skeleton, root: FloatArray) -> None:
    pos, glob = forward_kinematics(skel, quat.identity((skel.num_joints,)))
    np.testing.assert_allclose(pos, skel.rest_positions(), atol=1e-12)
    np.testing.assert_array_equal(glob, quat.identity((skel.num_joints,)))
    moved, _ = forward_kinematics(skel, quat.identity((skel.num_joints,)), root)
    np.testing.assert_allclose(moved, skel.rest_positions() + root, atol=1e-12)


@EXAMPLES
@given(posed())
def test_root_position_translates_everything(case: tuple[Skeleton, FloatArray, FloatArray]) -> None:
    skel, local, root = case
    at_origin, glob0 = forward_kinematics(skel, local)
    moved, glob = forward_kinematics(skel, local, root)
    np.testing.assert_allclose(moved, at_origin + root[:, None, :], atol=1e-12)
    np.testing.assert_array_equal(glob, glob0)


@EXAMPLES
@given(posed())
def test_fk_matches_chained_matrices(case: tuple[Skeleton, FloatArray, FloatArray]) -> None:
    skel, local, root = case
    pos, _ = forward_kinematics(skel, local, root)
    for f in range(len(local)):
        np.testing.assert_allclose(pos[f], fk_by_matrices(skel, local[f], root[f]), atol=1e-12)


@EXAMPLES
@given(posed())
def test_fk_preserves_bone_lengths(case: tuple[Skeleton, FloatArray, FloatArray]) -> None:
    skel, local, root = case
    pos, glob = forward_kinematics(skel, local, root)
    parents = np.array(skel.parents[1:], dtype=np.int64)
    lengths = np.linalg.norm(pos[:, 1:] - pos[:, parents], axis=-1)
    expected = np.broadcast_to(skel.bone_lengths()[1:], lengths.shape)
    np.testing.assert_allclose(lengths, expected, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(glob, axis=-1), 1.0, atol=1e-12)


@EXAMPLES
@given(posed())
def test_local_from_global_inverts_fk(case: tuple[Skeleton, FloatArray, FloatArray]) -> None:
    skel, local, _ = case
    _, glob = forward_kinematics(skel, local)
    np.testing.assert_allclose(local_from_global(skel, glob), local, atol=1e-12)


@EXAMPLES
@given(posed())
def test_global_from_local_from_global_round_trip(
    case: tuple[Skeleton, FloatArray, FloatArray],
) -> None:
    # Any set of global rotations is reachable: local_from_global, then FK, gives it back.
    skel, glob, _ = case
    _, again = forward_kinematics(skel, local_from_global(skel, glob))
    np.testing.assert_allclose(again, glob, atol=1e-12)


def test_root_rotation_turns_the_whole_body(canonical: Skeleton) -> None:
    turn = quat.from_axis_angle([0.0, 1.0, 0.0], 0.7)
    local = quat.identity((canonical.num_joints,))
    local[0] = turn
    pos, glob = forward_kinematics(canonical, local)
    np.testing.assert_allclose(pos, quat.rotate(turn, canonical.rest_positions()), atol=1e-15)
    np.testing.assert_allclose(glob, np.broadcast_to(turn, glob.shape), atol=1e-15)


def test_elbow_bend_moves_only_the_hand(canonical: Skeleton) -> None:
    local = quat.identity((canonical.num_joints,))
    elbow = canonical.index("LeftForeArm")
    local[elbow] = quat.from_axis_angle([0.0, 1.0, 0.0], -np.pi / 2)  # forearm turns to +z
    pos, _ = forward_kinematics(canonical, local)
    rest = canonical.rest_positions()
    hand = canonical.index("LeftHand")
    moved = np.any(np.abs(pos - rest) > 1e-12, axis=-1)
    assert list(np.flatnonzero(moved)) == [hand]
    np.testing.assert_allclose(pos[hand] - pos[elbow], [0.0, 0.0, 0.25], atol=1e-15)


def test_fk_batched_with_per_sample_offsets(canonical: Skeleton, rng: np.random.Generator) -> None:
    local = quat.normalize(rng.normal(size=(2, 5, canonical.num_joints, 4)))
    offsets = canonical.offsets * rng.uniform(0.5, 1.5, size=(2, 1, 1, 1))
    pos, _ = forward_kinematics(canonical, local, offsets=offsets)
    assert pos.shape == (2, 5, canonical.num_joints, 3)
    for b in range(2):
        ref, _ = forward_kinematics(canonical.with_offsets(offsets[b, 0]), local[b])
        np.testing.assert_allclose(pos[b], ref, atol=1e-15)


def test_fk_rejects_wrong_joint_count(chain: Skeleton) -> None:
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 4\)"):
        forward_kinematics(chain, quat.identity((4,)))
