"""Known joint-naming families and their canonical-joint tables.

Each table lists, per canonical joint, the source names that realise it (first present wins).
Names compare case-insensitively after dropping a namespace prefix (``mixamorig:Hips`` →
``hips``). Where a family has more spine or neck joints than the canonical skeleton, the table
picks the ones that keep the arm and leg chains exact: Spine2 is always the joint the clavicles
hang from, and the leftover joints (LHipJoint, Neck, lButtock, …) fold into the bones.
"""

from __future__ import annotations

from collections.abc import Mapping

CMU_MOTIONBUILDER = "CMU MotionBuilder"
CMU_ASF = "CMU ASF"
DAZ = "DAZ"
MIXAMO = "Mixamo"
AUTOMATIC = "automatic (topology)"

_Table = Mapping[str, tuple[str, ...]]


def _sided(
    left: dict[str, tuple[str, ...]], right_of: dict[str, str]
) -> dict[str, tuple[str, ...]]:
    """Add the Right* entries by renaming each left name with ``right_of``'s prefix swap."""
    out = dict(left)
    (lp, rp) = next(iter(right_of.items()))
    for joint, names in left.items():
        if joint.startswith("Left"):
            out["Right" + joint[4:]] = tuple(rp + n[len(lp) :] for n in names)
    return out


# cgspeed "MotionBuilder-friendly" CMU conversion: LowerBack, Spine, Spine1 are the ASF
# lowerback, upperback, thorax; Neck (zero length on Spine1) and Neck1 the lower/upper neck.
_MOTIONBUILDER: _Table = _sided(
    {
        "Hips": ("Hips",),
        "Spine": ("LowerBack",),
        "Spine1": ("Spine",),
        "Spine2": ("Spine1",),
        "Neck": ("Neck1", "Neck"),
        "Head": ("Head",),
        "LeftShoulder": ("LeftShoulder",),
        "LeftArm": ("LeftArm",),
        "LeftForeArm": ("LeftForeArm",),
        "LeftHand": ("LeftHand",),
        "LeftUpLeg": ("LeftUpLeg",),
        "LeftLeg": ("LeftLeg",),
        "LeftFoot": ("LeftFoot",),
        "LeftToeBase": ("LeftToeBase",),
    },
    {"Left": "Right"},
)

# ASF bone names used as BVH joint names (each joint sits at the start of its bone).
_ASF: _Table = _sided(
    {
        "Hips": ("root", "hips"),
        "Spine": ("lowerback",),
        "Spine1": ("upperback",),
        "Spine2": ("thorax",),
        "Neck": ("upperneck", "lowerneck"),
        "Head": ("head",),
        "LeftShoulder": ("lclavicle",),
        "LeftArm": ("lhumerus",),
        "LeftForeArm": ("lradius",),
        "LeftHand": ("lwrist",),
        "LeftUpLeg": ("lfemur",),
        "LeftLeg": ("ltibia",),
        "LeftFoot": ("lfoot",),
        "LeftToeBase": ("ltoes",),
    },
    {"l": "r"},
)

# cgspeed "DAZ-friendly" conversion (one spine joint below the chest: Spine1 is synthesised).
_DAZ: _Table = _sided(
    {
        "Hips": ("hip",),
        "Spine": ("abdomen", "abdomenLower"),
        "Spine1": ("abdomen2", "abdomenUpper"),
        "Spine2": ("chest", "chestUpper"),
        "Neck": ("neck", "neckLower"),
        "Head": ("head",),
        "LeftShoulder": ("lCollar",),
        "LeftArm": ("lShldr", "lShldrBend"),
        "LeftForeArm": ("lForeArm", "lForearmBend"),
        "LeftHand": ("lHand",),
        "LeftUpLeg": ("lThigh", "lThighBend"),
        "LeftLeg": ("lShin",),
        "LeftFoot": ("lFoot",),
        "LeftToeBase": ("lToe",),
    },
    {"l": "r"},
)

_MIXAMO: _Table = _sided(
    {
        "Hips": ("Hips",),
        "Spine": ("Spine",),
        "Spine1": ("Spine1",),
        "Spine2": ("Spine2",),
        "Neck": ("Neck",),
        "Head": ("Head",),
        "LeftShoulder": ("LeftShoulder",),
        "LeftArm": ("LeftArm",),
        "LeftForeArm": ("LeftForeArm",),
        "LeftHand": ("LeftHand",),
        "LeftUpLeg": ("LeftUpLeg",),
        "LeftLeg": ("LeftLeg",),
        "LeftFoot": ("LeftFoot",),
        "LeftToeBase": ("LeftToeBase",),
    },
    {"Left": "Right"},
)

FAMILY_TABLES: dict[str, _Table] = {
    CMU_MOTIONBUILDER: _MOTIONBUILDER,
    CMU_ASF: _ASF,
    DAZ: _DAZ,
    MIXAMO: _MIXAMO,
}

# Names only one family uses: they break ties (e.g. MotionBuilder vs Mixamo share most names).
FAMILY_SIGNATURES: dict[str, tuple[str, ...]] = {
    CMU_MOTIONBUILDER: ("LHipJoint", "RHipJoint", "LowerBack", "Neck1", "LThumb", "RThumb"),
    CMU_ASF: ("lhipjoint", "rhipjoint", "thorax", "lhumerus", "lfemur"),
    DAZ: ("lButtock", "rButtock", "abdomen", "lCollar", "lShldr"),
    MIXAMO: ("Spine2", "HeadTop_End", "LeftHandIndex1", "LeftToe_End"),
}


def normalize_name(name: str) -> str:
    """Case-folded name without a namespace prefix (``mixamorig:LeftArm`` → ``leftarm``)."""
    return name.rsplit(":", 1)[-1].strip().lower()


def lookup(table: _Table, names: tuple[str, ...]) -> dict[str, int]:
    """Canonical joint → source joint index for every table entry present in ``names``."""
    index: dict[str, int] = {}
    for i, n in enumerate(names):
        index.setdefault(normalize_name(n), i)
    found: dict[str, int] = {}
    for joint, candidates in table.items():
        hits = [index[c.lower()] for c in candidates if c.lower() in index]
        if hits:
            found[joint] = hits[0]
    return found


def signature_hits(family: str, names: tuple[str, ...]) -> int:
    present = {normalize_name(n) for n in names}
    return sum(s.lower() in present for s in FAMILY_SIGNATURES[family])
