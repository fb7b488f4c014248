"""Which source joint realises each canonical joint, and how missing ones are synthesised.

A :class:`JointMap` is found by name (a known naming family) or, failing that, from the tree
and its rest-pose geometry (auto_map.py). For every canonical joint it records

- ``source_joints``: the mapped source joint, or None when synthesised;
- ``rotation_joints``: the source joint whose *global* rotation the canonical joint takes;
- ``position_points``: the source point whose rest position places the canonical joint: a
  joint index j, or ``num_source_joints + e`` for End Site e.

Synthesis follows robot_retarget.skeleton.canonical: a missing Spine1 / Spine2 is a
zero-length copy of the joint below; a missing Shoulder is a copy of Spine2 placed at the arm;
a missing ToeBase sits at the foot's End Site (a zero-length copy of the foot if it has none).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_retarget.errors import JointMappingError
from robot_retarget.motion import name_families as nf
from robot_retarget.motion.auto_map import TreeGeometry, auto_map
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS, REQUIRED_JOINTS

FAMILIES: tuple[str, ...] = (*nf.FAMILY_TABLES, nf.AUTOMATIC)


@dataclass(frozen=True)
class JointMap:
    """How the canonical joints are taken from a source skeleton (see module docstring)."""

    family: str
    source_joints: tuple[int | None, ...]
    rotation_joints: tuple[int, ...]
    position_points: tuple[int, ...]
    num_source_joints: int

    @property
    def synthesized(self) -> tuple[str, ...]:
        """Canonical joints with no source joint of their own."""
        return tuple(
            n for n, s in zip(CANONICAL_JOINTS, self.source_joints, strict=True) if s is None
        )

    def source_names(self, names: Sequence[str]) -> dict[str, str | None]:
        """Canonical joint → source joint name (None when synthesised)."""
        return {
            c: None if s is None else names[s]
            for c, s in zip(CANONICAL_JOINTS, self.source_joints, strict=True)
        }


def _is_ancestor(parents: Sequence[int], a: int, j: int) -> bool:
    j = parents[j]
    while j >= 0:
        if j == a:
            return True
        j = parents[j]
    return False


def _consistent(found: dict[str, int], parents: Sequence[int]) -> bool:
    """Distinct source joints whose ancestry agrees with the canonical tree."""
    if len(set(found.values())) != len(found):
        return False
    for c, p in zip(CANONICAL_JOINTS, CANONICAL_PARENTS, strict=True):
        if c not in found or p < 0:
            continue
        anc = p
        while anc >= 0 and CANONICAL_JOINTS[anc] not in found:
            anc = CANONICAL_PARENTS[anc]
        if anc >= 0 and not _is_ancestor(parents, found[CANONICAL_JOINTS[anc]], found[c]):
            return False
    return True


_NEARLY = 2  # required joints a naming family may lack and still speak for the skeleton


def _contradicted(mapped: dict[str, int], named: dict[str, int]) -> dict[str, int]:
    """The canonical joints that ``mapped`` puts on a source joint whose name (``named``, a
    naming family's lookup) says it is another canonical joint."""
    named_as = {j: c for c, j in named.items()}
    return {c: j for c, j in mapped.items() if named_as.get(j, c) != c}


def _bind(family: str, found: dict[str, int], geo: TreeGeometry) -> JointMap:
    num = len(geo.parents)
    rot: dict[str, int] = {}
    point: dict[str, int] = {}
    for c, p in zip(CANONICAL_JOINTS, CANONICAL_PARENTS, strict=True):
        if c in found:
            rot[c] = point[c] = found[c]
            continue
        parent = CANONICAL_JOINTS[p]
        if c in ("Spine1", "Spine2"):
            rot[c], point[c] = rot[parent], point[parent]
        elif c.endswith("Shoulder"):
            rot[c], point[c] = rot["Spine2"], found[c.replace("Shoulder", "Arm")]
        elif c.endswith("ToeBase"):
            foot = found[c.replace("ToeBase", "Foot")]
            rot[c] = foot
            sites = [e for e, q in enumerate(geo.end_site_parents) if q == foot]
            if sites:
                dist = np.linalg.norm(geo.rest_end_sites[sites] - geo.rest_joints[foot], axis=-1)
                point[c] = num + sites[int(np.argmax(dist))]
            else:
                point[c] = foot
        else:  # a required joint: callers check those first
            raise JointMappingError(f"required joint {c} is not mapped", missing=(c,))
    return JointMap(
        family=family,
        source_joints=tuple(found.get(c) for c in CANONICAL_JOINTS),
        rotation_joints=tuple(rot[c] for c in CANONICAL_JOINTS),
        position_points=tuple(point[c] for c in CANONICAL_JOINTS),
        num_source_joints=num,
    )


def map_joints(
    names: Sequence[str],
    geo: TreeGeometry,
    *,
    family: str | None = None,
    path: str | Path | None = None,
) -> JointMap:
    """Map a source skeleton onto the canonical joints.

    ``family`` forces a naming family (one of FAMILIES); by default the best-matching known
    family is used, and the automatic topology mapping when no family names every required
    joint. Raises JointMappingError listing the required joints that cannot be found.
    """
    names_t = tuple(names)
    if family is not None and family not in FAMILIES:
        raise JointMappingError(
            f"unknown naming family {family!r}; use one of {', '.join(FAMILIES)}", path=path
        )
    ranked = []
    for fam, table in nf.FAMILY_TABLES.items():
        if family is not None and fam != family:
            continue
        found = nf.lookup(table, names_t)
        required = sum(r in found for r in REQUIRED_JOINTS)
        ranked.append(((required, len(found), nf.signature_hits(fam, names_t)), fam, found))
    ranked.sort(key=lambda r: r[0], reverse=True)
    for (required, _, _), fam, found in ranked:
        if required == len(REQUIRED_JOINTS) and _consistent(found, geo.parents):
            return _bind(fam, found, geo)
    layout = ""
    if family is None or family == nf.AUTOMATIC:
        auto = auto_map(geo)
        # A skeleton named after a family but missing one of its joints (a hand or a foot cut
        # off) still has a body's layout, and the tree's rules would then shift a whole chain
        # by a joint: such a mapping contradicts the names, and is refused. (Names that are all
        # there but nested against the tree are not trusted: the tree decides those.)
        named = ranked[0][2] if ranked else {}
        lacking = sum(r not in named for r in REQUIRED_JOINTS)
        # Only a family the names nearly complete speaks for the skeleton: one or two joints
        # named after it (a custom rig's "Spine1") must not veto the tree's mapping.
        wrong = _contradicted(auto.joints, named) if 0 < lacking <= _NEARLY else {}
        if (
            not wrong
            and all(r in auto.joints for r in REQUIRED_JOINTS)
            and _consistent(auto.joints, geo.parents)
        ):
            return _bind(nf.AUTOMATIC, auto.joints, geo)
        missing = tuple(r for r in REQUIRED_JOINTS if r not in auto.joints)
        if wrong:
            missing = ()
            shown = ", ".join(f"{c} on {names_t[j]}" for c, j in list(wrong.items())[:3])
            layout = f" (mapped by the tree's layout instead, it would put {shown})"
    else:
        missing = ()
    if ranked:
        best_missing = tuple(r for r in REQUIRED_JOINTS if r not in ranked[0][2])
        if not missing or (best_missing and len(best_missing) < len(missing)):
            missing = best_missing
        lacks = ", ".join(best_missing) or "nothing, but its joints are not nested as a body"
        hint = f"; the closest naming family, {ranked[0][1]}, lacks {lacks}{layout}"
    else:
        hint = ""
    if not missing:
        missing = REQUIRED_JOINTS
    raise JointMappingError(
        f"cannot map required canonical joints {', '.join(missing)} onto this skeleton{hint}. "
        "Rename the joints after a supported family (CMU MotionBuilder, CMU ASF, DAZ, Mixamo) or "
        "give the skeleton a recognisable hips / spine / two arms / two legs layout",
        missing=missing,
        path=path,
    )
