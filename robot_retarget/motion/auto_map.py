"""Map an unfamiliar skeleton onto the canonical joints from its tree and rest-pose geometry.

The rules, in order:

- Hips: the first joint from the root with three or more child branches.
- Spine: the Hips branch with the most joints (head and both arms). Legs: the two other
  branches that reach farthest.
- Up: from the leg ends towards the middle of the upper body.
- Each limb follows its *main chain* (at every joint, the child whose subtree reaches farthest),
  which steps past finger, eye and twist-bone side branches. On a leg chain the two longest
  consecutive bones are thigh + shin; the joints around them are
  UpLeg, Leg, Foot, and the one after the foot is ToeBase. Joints like LHipJoint or a buttock
  fold into the hip bone. On an arm chain the hand is where the fingers branch (else the
  chain's end), forearm and upper arm the two joints before it, and the one before the upper
  arm is Shoulder.
- Spine2 is the spine joint the arms and the neck branch from; Spine and Spine1 are the first
  and middle joints below it. The neck branch is the one pointing most upwards; the head is the
  end of its main chain, or the first joint on it with two or more children (eyes, jaw).
- Left and right: left = up × forward, forward being the direction from the feet to the toes
  (or +Z for Y-up / −Y for Z-up files when the feet carry no toe direction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS


@dataclass(frozen=True, eq=False)
class TreeGeometry:
    """A joint tree with End Sites, in the rest pose (any length unit)."""

    parents: tuple[int, ...]
    rest_joints: FloatArray  # (J, 3)
    end_site_parents: tuple[int, ...]
    rest_end_sites: FloatArray  # (E, 3)

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def end_sites_of(self, j: int) -> list[int]:
        return [e for e, p in enumerate(self.end_site_parents) if p == j]


@dataclass(frozen=True, eq=False)
class AutoMapResult:
    """Canonical joint → source joint index (absent: not found); ``up`` the inferred up vector."""

    joints: dict[str, int]
    up: FloatArray

    @property
    def missing(self) -> tuple[str, ...]:
        return tuple(n for n in CANONICAL_JOINTS if n not in self.joints)


class _Tree:
    def __init__(self, geo: TreeGeometry) -> None:
        self.geo = geo
        n = len(geo.parents)
        self.kids: list[list[int]] = [[] for _ in range(n)]
        for c, p in enumerate(geo.parents):
            if p >= 0:
                self.kids[p].append(c)
        self.ends: list[list[int]] = [[] for _ in range(n)]
        for e, p in enumerate(geo.end_site_parents):
            self.ends[p].append(e)
        # Subtree point sets (joint positions and End Sites), built children-first.
        self.points: list[list[FloatArray]] = [[] for _ in range(n)]
        self.size = [0] * n
        for j in range(n - 1, -1, -1):
            own = [geo.rest_joints[j]] + [geo.rest_end_sites[e] for e in self.ends[j]]
            self.points[j] = own + [p for c in self.kids[j] for p in self.points[c]]
            self.size[j] = len(own) + sum(self.size[c] for c in self.kids[j])

    def pos(self, j: int) -> FloatArray:
        return self.geo.rest_joints[j]

    def reach(self, j: int) -> float:
        """Farthest subtree point from joint j's parent (so it counts j's own bone)."""
        p = self.geo.parents[j]
        origin = self.pos(p) if p >= 0 else self.pos(j)
        return float(np.max(np.linalg.norm(np.array(self.points[j]) - origin, axis=-1)))

    def centroid(self, j: int) -> FloatArray:
        return np.asarray(np.mean(np.array(self.points[j]), axis=0), dtype=np.float64)

    def main_chain(self, start: int, stop_at_branch: bool = False) -> list[int]:
        chain = [start]
        while self.kids[chain[-1]]:
            kids = self.kids[chain[-1]]
            if stop_at_branch and len(kids) >= 2:
                break
            chain.append(max(kids, key=self.reach))
        return chain

    def end_point(self, j: int) -> FloatArray | None:
        """Farthest End Site of joint j, if it has any."""
        if not self.ends[j]:
            return None
        sites = self.geo.rest_end_sites[self.ends[j]]
        far = int(np.argmax(np.linalg.norm(sites - self.pos(j), axis=-1)))
        return np.asarray(sites[far], dtype=np.float64)


def _limb(chain: list[int], pos: FloatArray) -> int | None:
    """Index i in ``chain`` of the first of the two longest consecutive bones, or None."""
    if len(chain) < 3:
        return None
    seg = np.linalg.norm(np.diff(pos[chain], axis=0), axis=-1)
    pair = seg[:-1] + seg[1:]
    return int(np.argmax(pair))


def _arm(tree: _Tree, chain: list[int]) -> dict[str, int] | None:
    """Shoulder / Arm / ForeArm / Hand on an arm's main chain.

    The hand is where the fingers branch (the first joint from the third on with two or more
    children), else the chain's last joint. Forearm and upper arm are the joints before it at
    distinct positions (the last of co-located joints, whose rotation drives the next bone).
    """
    hand_at = next(
        (k for k in range(2, len(chain)) if len(tree.kids[chain[k]]) >= 2), len(chain) - 1
    )
    picked = [hand_at]
    for k in range(hand_at - 1, -1, -1):
        if len(picked) == 3:
            break
        if np.linalg.norm(tree.pos(chain[k]) - tree.pos(chain[picked[-1]])) > 1e-9:
            picked.append(k)
    if len(picked) < 3:
        return None
    hand, fore, upper = picked
    m = {"Arm": chain[upper], "ForeArm": chain[fore], "Hand": chain[hand]}
    if upper >= 1:
        m["Shoulder"] = chain[upper - 1]
    return m


def _unit(v: FloatArray) -> FloatArray | None:
    n = float(np.linalg.norm(v))
    return None if n < 1e-12 else v / n


def auto_map(geo: TreeGeometry) -> AutoMapResult:
    """Best-effort canonical mapping; check ``result.missing`` for what could not be found."""
    tree = _Tree(geo)
    pos = geo.rest_joints
    found: dict[str, int] = {}
    up_default = np.array([0.0, 1.0, 0.0])

    hips = 0
    while len(tree.kids[hips]) == 1:
        hips = tree.kids[hips][0]
    if len(tree.kids[hips]) < 3:
        return AutoMapResult(found, up_default)
    found["Hips"] = hips
    kids = sorted(tree.kids[hips], key=lambda c: tree.size[c], reverse=True)
    spine_root = kids[0]
    legs = sorted(kids[1:], key=tree.reach, reverse=True)[:2]

    leg_chains = [tree.main_chain(c) for c in legs]
    leg_ends = [tree.end_point(ch[-1]) for ch in leg_chains]
    leg_tips = [pos[ch[-1]] if e is None else e for ch, e in zip(leg_chains, leg_ends, strict=True)]
    up = _unit(tree.centroid(spine_root) - np.mean(leg_tips, axis=0))
    if up is None:
        return AutoMapResult(found, up_default)

    # Legs: UpLeg, Leg, Foot around the two longest bones; ToeBase after the foot.
    leg_maps: list[dict[str, int]] = []
    toe_dirs: list[FloatArray] = []
    for chain, end in zip(leg_chains, leg_ends, strict=True):
        i = _limb(chain, pos)
        if i is None:
            continue
        m = {"UpLeg": chain[i], "Leg": chain[i + 1], "Foot": chain[i + 2]}
        if len(chain) > i + 3:
            m["ToeBase"] = chain[i + 3]
            toe_dirs.append(pos[chain[i + 3]] - pos[chain[i + 2]])
        elif end is not None and chain[-1] == chain[i + 2]:
            toe_dirs.append(end - pos[chain[i + 2]])
        leg_maps.append(m)

    # Forward from the toes (perpendicular to up), else the file's conventional facing.
    fwd = np.sum(toe_dirs, axis=0) if toe_dirs else np.zeros(3)
    fwd = _unit(fwd - np.dot(fwd, up) * up)
    if fwd is None:
        guess = (
            np.array([0.0, 0.0, 1.0]) if abs(up[2]) < 0.7 else np.array([0.0, -np.sign(up[2]), 0.0])
        )
        fwd = _unit(guess - np.dot(guess, up) * up)
    left = np.cross(up, fwd) if fwd is not None else np.array([1.0, 0.0, 0.0])

    if len(leg_maps) == 2:
        sides = sorted(
            leg_maps, key=lambda m: float(np.dot(pos[m["Foot"]] + pos[m["UpLeg"]], left))
        )
        for side, m in zip(("Right", "Left"), sides, strict=True):
            for part, j in m.items():
                found[side + part] = j

    # Spine: descend to the joint the arms and neck branch from.
    path = [spine_root]
    while True:
        big = sorted((tree.size[c] for c in tree.kids[path[-1]]), reverse=True)
        if len(big) >= 3 and big[2] >= 3:
            break
        if not tree.kids[path[-1]]:
            return AutoMapResult(found, up)
        path.append(max(tree.kids[path[-1]], key=lambda c: tree.size[c]))
    branch = path[-1]
    below = path[:-1]
    found["Spine2"] = branch
    if below:
        found["Spine"] = below[0]
        if len(below) >= 2:
            found["Spine1"] = below[len(below) // 2] if len(below) > 2 else below[1]
    else:
        found["Spine"] = branch
        del found["Spine2"]

    limbs = [c for c in tree.kids[branch] if tree.size[c] >= 3]
    neck_root = max(limbs, key=lambda c: float(np.dot(tree.centroid(c) - pos[branch], up)))
    neck_chain = tree.main_chain(neck_root, stop_at_branch=True)
    if len(neck_chain) >= 2:
        found["Head"] = neck_chain[-1]
        above = [
            j for j in neck_chain[:-1] if np.linalg.norm(pos[j] - pos[branch]) > 1e-9
        ] or neck_chain[:-1]
        found["Neck"] = above[0]

    def lateral_reach(c: int) -> float:
        d = np.array(tree.points[c]) - pos[branch]
        return float(np.max(np.linalg.norm(d - np.outer(d @ up, up), axis=-1)))

    arms = sorted((c for c in limbs if c != neck_root), key=lateral_reach, reverse=True)[:2]
    arm_maps: list[dict[str, int]] = []
    for a in arms:
        arm = _arm(tree, tree.main_chain(a))
        if arm is not None:
            arm_maps.append(arm)
    if len(arm_maps) == 2:
        sides = sorted(arm_maps, key=lambda m: float(np.dot(pos[m["Hand"]], left)))
        for side, m in zip(("Right", "Left"), sides, strict=True):
            for part, j in m.items():
                found[side + part] = j
    return AutoMapResult(found, up)
