"""A skeleton as armatures (bones), pooled towards its primal skeleton (SAN, Aberman et al. 2020).

Skeleton-aware networks see a skeleton as a graph whose *edges* are its armatures: the bone
from a joint's parent to the joint. Convolution kernels cover the armatures within graph
distance d of each armature; *pooling* merges consecutive armatures along a chain (a run of
nodes of degree two), until every chain between branching nodes and end-effectors is one
armature: the *primal skeleton*. Homeomorphic skeletons (same chains, different numbers of
joints along them) pool to the same primal skeleton, which is what lets one latent space serve
skeletons of different structure.

:class:`ArmatureTopology` is built from a joint tree and its end-effectors in a fixed order
(left foot, right foot, head, left hand, right hand). Joints off the paths from the root to
those end-effectors (fingers, eyes, the toe of a skeleton that has one where another has not)
are left out, and children are visited in end-effector order, so that armature chains come in
the same order on every skeleton: the primal skeleton's chain i means the same body part for
every source. Index 0 is the *root armature* (the root's rotation and movement), which is
adjacent to every armature leaving the root and is never pooled.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

from robot_retarget.errors import RetargetError

END_EFFECTORS: tuple[str, ...] = ("LeftFoot", "RightFoot", "Head", "LeftHand", "RightHand")
"""The end-effectors every topology names, in the order its chains are visited."""

ROOT = 0
"""Index of the root armature at every level."""


class TopologyError(RetargetError):
    """A skeleton cannot be read as armatures as asked (names the skeleton and the problem)."""

    def __init__(self, message: str, *, skeleton: str) -> None:
        self.skeleton = skeleton
        super().__init__(f"{skeleton}: {message}")


@dataclass(frozen=True)
class PoolLevel:
    """One level of a topology: armature ``a``'s parent armature is ``parents[a]`` (−1 for the
    root armature; armatures leaving the root joint have parent 0, the root armature)."""

    parents: tuple[int, ...]

    @property
    def size(self) -> int:
        return len(self.parents)

    def neighbours(self, distance: int) -> tuple[tuple[int, ...], ...]:
        """Per armature, the armatures within ``distance`` in the armature graph (itself
        included), ascending. Two armatures are adjacent when they share a joint: parent and
        child, or siblings (the root armature counts as the parent of those leaving the root)."""
        n = self.size
        adjacent: list[set[int]] = [set() for _ in range(n)]
        for a, p in enumerate(self.parents):
            if p >= 0:
                adjacent[a].add(p)
                adjacent[p].add(a)
        for p in range(n):
            kids = [a for a, q in enumerate(self.parents) if q == p]
            for a in kids:
                adjacent[a].update(k for k in kids if k != a)
        out: list[tuple[int, ...]] = []
        for a in range(n):
            seen = {a}
            frontier = {a}
            for _ in range(distance):
                frontier = {b for f in frontier for b in adjacent[f]} - seen
                seen |= frontier
            out.append(tuple(sorted(seen)))
        return tuple(out)


@dataclass(frozen=True)
class ArmatureTopology:
    """The armatures of a joint tree, in chain order, with their pooling (see module docstring).

    ``joints[a]`` (a ≥ 1) is the source joint index at armature a's far end (the armature is
    the bone from its parent to it); ``joints[0]`` is the root joint. ``chains`` lists each
    primal chain's armatures from the root side outwards.
    """

    name: str
    joint_names: tuple[str, ...]
    joints: tuple[int, ...]
    base: PoolLevel
    chains: tuple[tuple[int, ...], ...]
    end_effectors: tuple[int, ...]

    @classmethod
    def from_tree(
        cls,
        name: str,
        joint_names: Sequence[str],
        parents: Sequence[int],
        end_effectors: Sequence[int],
    ) -> ArmatureTopology:
        """Armatures of the tree (``parents[j]`` < j, −1 for the root) on the paths from the
        root to ``end_effectors`` (joint indices, in :data:`END_EFFECTORS` order)."""
        n = len(parents)
        if len(joint_names) != n:
            raise TopologyError(f"{len(joint_names)} names for {n} joints", skeleton=name)
        if len(end_effectors) != len(END_EFFECTORS):
            raise TopologyError(
                f"needs {len(END_EFFECTORS)} end-effectors ({', '.join(END_EFFECTORS)}), got "
                f"{len(end_effectors)}",
                skeleton=name,
            )
        if len(set(end_effectors)) != len(end_effectors) or any(
            not 0 < e < n for e in end_effectors
        ):
            raise TopologyError(
                f"end-effectors must be distinct non-root joints, got {list(end_effectors)}",
                skeleton=name,
            )
        order: dict[int, int] = {}  # joint → first end-effector rank in its subtree
        for rank, e in enumerate(end_effectors):
            j = e
            while j >= 0:
                order.setdefault(j, rank)
                j = parents[j]
        if 0 not in order:
            raise TopologyError("the end-effectors do not hang from joint 0", skeleton=name)
        kept_children: dict[int, list[int]] = {j: [] for j in order}
        for j in sorted(order):
            if parents[j] >= 0:
                kept_children[parents[j]].append(j)
        for kids in kept_children.values():
            kids.sort(key=lambda k: order[k])
        for e in end_effectors:
            if kept_children[e]:
                raise TopologyError(
                    f"end-effector {joint_names[e]!r} has another end-effector below it",
                    skeleton=name,
                )

        joints: list[int] = [0]
        arm_parent: list[int] = [-1]
        arm_of: dict[int, int] = {0: ROOT}

        def visit(j: int) -> None:
            for k in kept_children[j]:
                arm_of[k] = len(joints)
                joints.append(k)
                arm_parent.append(arm_of[j])
                visit(k)

        visit(0)
        chains: list[tuple[int, ...]] = []
        for a in range(1, len(joints)):
            start = parents[joints[a]]
            if start != 0 and len(kept_children[start]) == 1:
                continue  # not the first armature of a chain
            chain = [a]
            j = joints[a]
            while len(kept_children[j]) == 1:
                j = kept_children[j][0]
                chain.append(arm_of[j])
            chains.append(tuple(chain))
        return cls(
            name=name,
            joint_names=tuple(joint_names),
            joints=tuple(joints),
            base=PoolLevel(tuple(arm_parent)),
            chains=tuple(chains),
            end_effectors=tuple(end_effectors),
        )

    def spec(self) -> dict[str, Any]:
        """The kept tree as JSON-compatible data (armature order); :meth:`from_spec` rebuilds
        an equal topology (joint indices then refer to the kept tree)."""
        return {
            "name": self.name,
            "joint_names": list(self.armature_names),
            "parents": list(self.base.parents),
            "end_effectors": [self.joints.index(e) for e in self.end_effectors],
        }

    @classmethod
    def from_spec(cls, spec: Mapping[str, Any]) -> ArmatureTopology:
        try:
            return cls.from_tree(
                str(spec["name"]),
                [str(n) for n in spec["joint_names"]],
                [int(p) for p in spec["parents"]],
                [int(e) for e in spec["end_effectors"]],
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise TopologyError(
                f"bad topology spec: {exc}", skeleton=str(spec.get("name"))
            ) from exc

    def same_structure(self, other: ArmatureTopology) -> bool:
        """Whether ``other`` has the same kept joints (names and tree): the same domain."""
        return (self.armature_names, self.base.parents) == (
            other.armature_names,
            other.base.parents,
        )

    @property
    def num_armatures(self) -> int:
        """Armatures including the root armature."""
        return len(self.joints)

    @property
    def armature_names(self) -> tuple[str, ...]:
        """The joint at each armature's far end (the root joint for armature 0)."""
        return tuple(self.joint_names[j] for j in self.joints)

    @cached_property
    def primal_signature(self) -> tuple[int, ...]:
        """Per primal chain, the index of the chain it hangs from (−1: from the root).
        Equal signatures ⇔ the skeletons are homeomorphic (with chains in the same order)."""
        chain_of = {a: c for c, chain in enumerate(self.chains) for a in chain}
        return tuple(chain_of.get(self.base.parents[chain[0]], -1) for chain in self.chains)

    def pooling(self, steps: int) -> tuple[tuple[tuple[int, ...], ...], ...]:
        """For each of ``steps`` pooling steps, the groups of the level below that become one
        armature (groups index the level below; group 0 is the root armature alone). Each
        step but the last merges consecutive pairs along every chain; the last merges whole
        chains, so the top level is the primal skeleton: the root armature + one per chain."""
        if steps < 1:
            raise ValueError(f"pooling needs at least one step, got {steps}")
        chains = [list(c) for c in self.chains]
        out: list[tuple[tuple[int, ...], ...]] = []
        for s in range(steps):
            last = s == steps - 1
            groups: list[tuple[int, ...]] = [(ROOT,)]
            new_chains: list[list[int]] = []
            for chain in chains:
                size = len(chain) if last else 2
                parts = [tuple(chain[i : i + size]) for i in range(0, len(chain), size)]
                new_chains.append(list(range(len(groups), len(groups) + len(parts))))
                groups.extend(parts)
            out.append(tuple(groups))
            chains = new_chains
        return tuple(out)

    def levels(self, steps: int) -> tuple[PoolLevel, ...]:
        """The armature graph at each level: the base, then after each pooling step."""
        levels = [self.base]
        for groups in self.pooling(steps):
            below = levels[-1]
            group_of = {a: g for g, members in enumerate(groups) for a in members}
            parents = tuple(
                -1 if g == ROOT else group_of[below.parents[members[0]]]
                for g, members in enumerate(groups)
            )
            levels.append(PoolLevel(parents))
        return tuple(levels)


def check_homeomorphic(topologies: Sequence[ArmatureTopology]) -> None:
    """Raise TopologyError unless every topology pools to the same primal skeleton."""
    if not topologies:
        return
    first = topologies[0]
    for t in topologies[1:]:
        if t.primal_signature != first.primal_signature:
            raise TopologyError(
                f"not homeomorphic to {first.name!r}: its chains hang from "
                f"{list(t.primal_signature)}, {first.name!r}'s from "
                f"{list(first.primal_signature)} (same end-effectors, same branching needed)",
                skeleton=t.name,
            )


def canonical_topology() -> ArmatureTopology:
    """The canonical 22-joint skeleton's armatures (robot_retarget.skeleton.canonical)."""
    from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS

    ends = ("LeftToeBase", "RightToeBase", "Head", "LeftHand", "RightHand")
    return ArmatureTopology.from_tree(
        "canonical",
        CANONICAL_JOINTS,
        CANONICAL_PARENTS,
        [CANONICAL_JOINTS.index(n) for n in ends],
    )
