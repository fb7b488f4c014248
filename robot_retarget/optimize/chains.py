"""Which joints move which segments: coupled groups of segments (numpy, from the config).

Segments (a start and an end frame, or the means of several) that depend on disjoint sets of
joints are independent: a limb's branch can be chosen, or a limit found, per group.
"""

from __future__ import annotations

from collections.abc import Sequence
from collections.abc import Set as AbstractSet

import numpy as np
import numpy.typing as npt

from robot_retarget.robot.config import RobotConfig

# A segment: (frames whose mean is its start, frames whose mean is its end).
SegmentFrames = tuple[tuple[str, ...], tuple[str, ...]]


def joints_above(config: RobotConfig, frame: str) -> set[int]:
    """Indices of the joints that move ``frame``'s origin (in the root frame)."""
    joint_of_child = {jc.child_link: i for i, jc in enumerate(config.joints)}
    parent_of = {jc.child_link: jc.parent_link for jc in config.joints}
    parent_of.update({f.name: f.parent_link for f in config.frames})
    out: set[int] = set()
    # A link's origin lies on its own joint's axis: only the joints above it move it.
    name = parent_of.get(frame, frame) if frame in joint_of_child else frame
    while name in parent_of:
        if name in joint_of_child:
            out.add(joint_of_child[name])
        name = parent_of[name]
    return out


def coupled_groups(
    config: RobotConfig, segments: Sequence[SegmentFrames], held: AbstractSet[int] = frozenset()
) -> tuple[tuple[list[int], ...], tuple[npt.NDArray[np.int64], ...]]:
    """Segments grouped by shared joints (union-find), with each group's joint indices;
    joints in ``held`` (e.g. a spine every limb hangs from) neither couple segments nor belong
    to a group."""
    deps = [
        set().union(*(joints_above(config, f) for f in (*starts, *ends))) - held
        for starts, ends in segments
    ]
    group_of = list(range(len(segments)))

    def root(i: int) -> int:
        while group_of[i] != i:
            i = group_of[i]
        return i

    for a in range(len(segments)):
        for b in range(a + 1, len(segments)):
            if deps[a] & deps[b]:
                group_of[root(b)] = root(a)
    roots = sorted({root(i) for i in range(len(segments))})
    groups = tuple([i for i in range(len(segments)) if root(i) == r] for r in roots)
    joints = tuple(
        np.array(sorted(set().union(*(deps[i] for i in g))), dtype=np.int64) for g in groups
    )
    return groups, joints
