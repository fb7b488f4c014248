"""Index tables of a kinematic tree for batched forward kinematics (numpy, cached).

Forward kinematics of one frame in a few large array operations instead of a loop over joints:
global rotations by *pointer jumping* (log₂ depth rounds of ``G_n ← G_anc(n) · G_n``) and joint
positions as one product of the bone vectors with the 0/1 ancestor matrix. The torch FK layer,
the optimizer's targets and the live numpy steps share these tables.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from robot_retarget.array_types import FloatArray


def validated_parents(parents: Sequence[int]) -> tuple[int, ...]:
    """``parents`` as ints, checked for the order every table here assumes: joint 0 is the root
    (parent -1) and each other joint's parent comes before it."""
    out = tuple(int(p) for p in parents)
    if not out or out[0] != -1:
        raise ValueError(f"joint 0 must be the root (parent -1), got parents {list(out)}")
    for i, p in enumerate(out[1:], start=1):
        if not 0 <= p < i:
            raise ValueError(
                f"joint {i}'s parent {p} must come before it (parents must come before their "
                "children)"
            )
    return out


def pointer_jumps(parents: Sequence[int]) -> tuple[tuple[int, ...], ...]:
    """Ancestor index lists for pointer jumping over J joints, each of length J + 1.

    Index J is a sentinel "parent of the root" whose entry holds the identity. Round r maps
    joint n to its 2^r-th ancestor (the sentinel once past the root); after all rounds every
    joint's product covers its whole chain. Round 0 is the parent list itself.
    """
    return _pointer_jumps(tuple(int(p) for p in parents))


@lru_cache(maxsize=16)
def _pointer_jumps(parents: tuple[int, ...]) -> tuple[tuple[int, ...], ...]:
    j = len(parents)
    parent = (*(j if p < 0 else p for p in parents), j)
    depth = [0] * j
    for i in range(1, j):
        depth[i] = depth[parents[i]] + 1
    jumps = [parent]
    while 2 ** len(jumps) < max(depth, default=0) + 1:
        prev = jumps[-1]
        jumps.append(tuple(prev[prev[i]] for i in range(j + 1)))
    return tuple(jumps)


def ancestor_matrix(parents: Sequence[int]) -> FloatArray:
    """(J, J) 0/1 matrix: row n marks the joints whose bone vectors add up to n's position
    relative to the root (the root's own offset never moves a joint; the root position does)."""
    return _ancestor_matrix(tuple(int(p) for p in parents))


@lru_cache(maxsize=16)
def _ancestor_matrix(parents: tuple[int, ...]) -> FloatArray:
    chain = np.zeros((len(parents), len(parents)))
    for n in range(len(parents)):
        k = n
        while k > 0:
            chain[n, k] = 1.0
            k = parents[k]
    chain.setflags(write=False)
    return chain
