"""A skeleton (joint names, parents, rest offsets) and its forward kinematics in numpy.

Forward kinematics follows the FK layer of the seed papers (NKN eq. 1; BVH semantics):

    G_n = G_parent(n) ⊗ q_n            (global rotation)
    p_n = p_parent(n) + G_parent(n) s_n (global position)

with q_n the joint's local rotation relative to its parent and s_n its rest offset from the
parent in the parent's frame. Joints are stored in topological order (parent index < own index),
so one pass over the joints suffices.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.geometry import quaternion as quat


@dataclass(frozen=True)
class Skeleton:
    """Joint tree: ``names[i]`` has parent ``parents[i]`` (−1 for the root, always index 0)
    and rest offset ``offsets[i]`` (3,) from the parent, in the parent's rest frame, metres
    unless stated otherwise."""

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: FloatArray = field(repr=False)

    def __post_init__(self) -> None:
        offsets = np.array(self.offsets, dtype=np.float64)  # own copy: callers may mutate theirs
        n = len(self.names)
        if n == 0:
            raise ValueError("a skeleton needs at least one joint")
        if len(self.parents) != n or offsets.shape != (n, 3):
            raise ValueError(
                f"skeleton sizes disagree: {n} names, {len(self.parents)} parents, "
                f"offsets of shape {offsets.shape} (expected ({n}, 3))"
            )
        if self.parents[0] != -1:
            raise ValueError(f"joint 0 ({self.names[0]}) must be the root (parent −1)")
        for i, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < i:
                raise ValueError(
                    f"joint {i} ({self.names[i]}) has parent {p}; parents must come first"
                )
        if len(set(self.names)) != n:
            dupes = sorted({x for x in self.names if self.names.count(x) > 1})
            raise ValueError(f"duplicate joint names: {dupes}")
        if not np.all(np.isfinite(offsets)):
            raise ValueError("skeleton offsets must be finite")
        offsets.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))

    @classmethod
    def from_parent_names(
        cls, names: Sequence[str], parent_names: Sequence[str | None], offsets: npt.ArrayLike
    ) -> Skeleton:
        """Build from parent *names* (None for the root) in topological order."""
        index = {name: i for i, name in enumerate(names)}
        parents = tuple(-1 if p is None else index[p] for p in parent_names)
        return cls(tuple(names), parents, np.asarray(offsets, dtype=np.float64))

    @cached_property
    def depth_levels(self) -> tuple[tuple[IntArray, IntArray], ...]:
        """(joint indices, their parents' indices) for each tree depth below the root."""
        depth = [0] * self.num_joints
        for i in range(1, self.num_joints):
            depth[i] = depth[self.parents[i]] + 1
        levels = []
        for level in range(1, max(depth) + 1):
            idx = [i for i, d in enumerate(depth) if d == level]
            levels.append((as_index_array(idx), as_index_array([self.parents[i] for i in idx])))
        return tuple(levels)

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of a joint by name; KeyError lists the joints that exist."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint {name!r}; joints are {list(self.names)}") from None

    def children(self, i: int) -> tuple[int, ...]:
        return tuple(j for j, p in enumerate(self.parents) if p == i)

    def bone_lengths(self) -> FloatArray:
        """Length of each joint's offset (0 for the root)."""
        return np.asarray(np.linalg.norm(self.offsets, axis=-1), dtype=np.float64)

    def rest_positions(self) -> FloatArray:
        """Global joint positions (J, 3) in the rest pose, root at the origin."""
        pos = np.zeros((self.num_joints, 3))
        for i, p in enumerate(self.parents):
            if p >= 0:
                pos[i] = pos[p] + self.offsets[i]
        return pos

    def scaled(self, factor: float) -> Skeleton:
        return Skeleton(self.names, self.parents, self.offsets * factor)

    def with_offsets(self, offsets: npt.ArrayLike) -> Skeleton:
        return Skeleton(self.names, self.parents, np.asarray(offsets, dtype=np.float64))


def forward_kinematics(
    skeleton: Skeleton,
    local_quats: npt.ArrayLike,
    root_pos: npt.ArrayLike | None = None,
    offsets: npt.ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Global positions (…, J, 3) and global rotations (…, J, 4) from local rotations (…, J, 4).

    ``root_pos`` (…, 3) translates the root (default: origin). ``offsets`` (…, J, 3) overrides the
    skeleton's rest offsets, e.g. per-sample skeletons in a batch.
    """
    q = quat.as_float_array(local_quats)
    j = skeleton.num_joints
    if q.shape[-2:] != (j, 4):
        raise ValueError(f"local rotations must have shape (..., {j}, 4), got {q.shape}")
    lead = q.shape[:-2]
    s = skeleton.offsets if offsets is None else quat.as_float_array(offsets)
    s = np.broadcast_to(s, (*lead, j, 3))
    glob_q = np.empty_like(q)
    pos = np.empty((*lead, j, 3))
    pos[..., 0, :] = 0.0 if root_pos is None else quat.as_float_array(root_pos)
    glob_q[..., 0, :] = q[..., 0, :]
    # One vectorised step per tree depth (7 for the canonical skeleton) instead of per joint.
    for idx, par in skeleton.depth_levels:
        parent_q = glob_q[..., par, :]
        pos[..., idx, :] = pos[..., par, :] + quat.rotate(parent_q, s[..., idx, :])
        glob_q[..., idx, :] = quat.mul(parent_q, q[..., idx, :])
    return pos, glob_q


def local_from_global(skeleton: Skeleton, global_quats: npt.ArrayLike) -> FloatArray:
    """Local rotations (…, J, 4) from global ones: q_n = G_parent(n)* ⊗ G_n."""
    g = quat.as_float_array(global_quats)
    local = g.copy()
    parents = np.array(skeleton.parents[1:], dtype=np.int64)  # int even when empty
    local[..., 1:, :] = quat.mul(quat.conjugate(g[..., parents, :]), g[..., 1:, :])
    return local


def as_index_array(values: Sequence[int]) -> IntArray:
    out: IntArray = np.asarray(values, dtype=np.int64)
    return out
