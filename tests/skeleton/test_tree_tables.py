"""Pointer-jumping and ancestor tables of kinematic trees."""

from __future__ import annotations

import numpy as np

from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, default_canonical_skeleton
from robot_retarget.skeleton.tree_tables import ancestor_matrix, pointer_jumps


def test_jumps_reach_every_ancestor() -> None:
    parents = CANONICAL_PARENTS
    j = len(parents)
    jumps = pointer_jumps(parents)
    assert jumps[0] == (*[j if p < 0 else p for p in parents], j)
    # Composing the rounds as FK does covers each joint's whole chain exactly once.
    covered = [{n} for n in range(j)] + [set()]
    for anc in jumps:
        covered = [covered[anc[n]] | covered[n] for n in range(j + 1)]
    for n in range(j):
        chain, k = set(), n
        while k >= 0:
            chain.add(k)
            k = parents[k]
        assert covered[n] == chain


def test_ancestor_matrix_sums_bones_to_rest_positions() -> None:
    skeleton = default_canonical_skeleton()
    chain = ancestor_matrix(skeleton.parents)
    rest = skeleton.rest_positions()
    np.testing.assert_allclose(chain @ skeleton.offsets, rest - rest[0], atol=1e-12)
    assert not chain.flags.writeable


def test_a_lone_root() -> None:
    assert pointer_jumps((-1,)) == ((1, 1),)
    np.testing.assert_array_equal(ancestor_matrix((-1,)), np.zeros((1, 1)))
