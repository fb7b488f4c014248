"""Joints a tracker holds in place while they are occluded, carried along with their parent.

A mocap system that loses a marker, or a pose estimator that loses a limb, may keep sending that
joint's last seen position while the rest of the body moves on (the ``dropout`` kind of
:mod:`robot_retarget.evaluation.live_corruption`). Solved as it is, the frozen joint drags its
bone toward a point in the room: a wrist held for half a second while the performer walks points
the forearm backwards. A measured joint that moves never repeats its position to the last bit, so
a joint whose position is bitwise the previous packet's while another joint of the frame moved is
taken as frozen, and placed at its parent (itself placed first, root outward) plus the bone
vector it had when last seen moving. A joint that is really still keeps the bone it has: it stays
where it is (to rounding) if its parent does (a trunk at rest while the arms move), and moves
with its parent if the parent moved (a sender that quantises or holds still joints has them
carried along). A frame repeated whole gets the previous frame's answer, and the root is never
filled (its world position is the one the rest hangs on).

Stateful per stream: :meth:`FrozenJointFill.reset` at a sender restart.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.skeleton.tree_tables import validated_parents


class FrozenJointFill:
    """``fill(positions (J, 3))`` → positions with frozen joints carried by their parents.

    ``parents[j]`` is joint j's parent index (-1 for the root, which must be joint 0); parents
    must come before their children. :attr:`frozen` is the last frame's mask of filled joints."""

    def __init__(self, parents: Sequence[int]) -> None:
        self._parents = validated_parents(parents)
        self._sent: list[list[float]] | None = None  # the last frame as sent
        self._placed: FloatArray | None = None  # the last frame as filled
        self._held: dict[int, FloatArray] = {}  # frozen joint → its bone when last seen moving

    @property
    def frozen(self) -> BoolArray:
        mask = np.zeros(len(self._parents), dtype=bool)
        mask[list(self._held)] = True
        return mask

    def reset(self) -> None:
        """A new stream: nothing is known of the joints yet."""
        self._sent = self._placed = None
        self._held.clear()

    def __call__(self, positions: npt.ArrayLike) -> FloatArray:
        p = np.array(positions, dtype=np.float64)
        n = len(self._parents)
        if p.shape != (n, 3):
            raise ValueError(f"positions must have shape ({n}, 3), got {p.shape}")
        # Row-by-row comparison of Python lists: exact, and cheaper than numpy calls here.
        rows = p.tolist()
        sent, placed = self._sent, self._placed
        self._sent = rows
        if sent is None or placed is None:
            self._placed = p.copy()
            return p
        same = [a == b for a, b in zip(rows, sent, strict=True)]
        if not any(same[1:]):  # the usual frame: every joint moved
            self._held.clear()
            self._placed = p.copy()
            return p
        if all(same):  # the same frame again: the same answer (frozen joints stay filled)
            return placed.copy()
        held = {}
        for j in range(1, n):
            if same[j]:
                parent = self._parents[j]
                bone = self._held.get(j)
                if bone is None:  # frozen from this frame on: its bone as last placed
                    bone = placed[j] - placed[parent]
                held[j] = bone
                p[j] = p[parent] + bone  # parents first: the parent is already placed
        self._held = held
        self._placed = p.copy()
        return p
