"""The canonical 22-joint human skeleton shared by NKN, PMnet and TDCN.

Every motion source is mapped onto these joints (in this order); every network consumes and
produces rotations for them; every robot config says which of its frames realise which bones.
Coordinates: metres, Y up (as in BVH files), the rest pose a T-pose facing +Z.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from robot_retarget.skeleton.skeleton import Skeleton


class Joint(IntEnum):
    """Canonical joint indices (topological order)."""

    Hips = 0
    Spine = 1
    Spine1 = 2
    Spine2 = 3
    Neck = 4
    Head = 5
    LeftShoulder = 6
    LeftArm = 7
    LeftForeArm = 8
    LeftHand = 9
    RightShoulder = 10
    RightArm = 11
    RightForeArm = 12
    RightHand = 13
    LeftUpLeg = 14
    LeftLeg = 15
    LeftFoot = 16
    LeftToeBase = 17
    RightUpLeg = 18
    RightLeg = 19
    RightFoot = 20
    RightToeBase = 21


CANONICAL_JOINTS: tuple[str, ...] = tuple(j.name for j in Joint)

_PARENT_NAMES: dict[str, str | None] = {
    "Hips": None,
    "Spine": "Hips",
    "Spine1": "Spine",
    "Spine2": "Spine1",
    "Neck": "Spine2",
    "Head": "Neck",
    "LeftShoulder": "Spine2",
    "LeftArm": "LeftShoulder",
    "LeftForeArm": "LeftArm",
    "LeftHand": "LeftForeArm",
    "RightShoulder": "Spine2",
    "RightArm": "RightShoulder",
    "RightForeArm": "RightArm",
    "RightHand": "RightForeArm",
    "LeftUpLeg": "Hips",
    "LeftLeg": "LeftUpLeg",
    "LeftFoot": "LeftLeg",
    "LeftToeBase": "LeftFoot",
    "RightUpLeg": "Hips",
    "RightLeg": "RightUpLeg",
    "RightFoot": "RightLeg",
    "RightToeBase": "RightFoot",
}

CANONICAL_PARENTS: tuple[int, ...] = tuple(
    -1 if _PARENT_NAMES[n] is None else CANONICAL_JOINTS.index(str(_PARENT_NAMES[n]))
    for n in CANONICAL_JOINTS
)

# Joints every motion source must provide. The others may be synthesised: a missing Spine1 /
# Spine2 becomes a zero-length copy of the joint below (as NKN does for 17-joint input), a
# missing ToeBase comes from the foot's End Site, a missing Shoulder (clavicle) is a zero-length
# copy of Spine2 placed at the arm.
REQUIRED_JOINTS: tuple[str, ...] = (
    "Hips", "Spine", "Neck", "Head",
    "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand",
    "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot",
)  # fmt: skip

# Left/right pairs, for mirroring and symmetry checks.
MIRROR_PAIRS: tuple[tuple[str, str], ...] = tuple(
    (n, "Right" + n[4:]) for n in CANONICAL_JOINTS if n.startswith("Left")
)

# Each limb as a chain from the trunk outward, (left, right): what a pose estimator swaps.
ARM_CHAINS: tuple[tuple[Joint, ...], tuple[Joint, ...]] = (
    (Joint.LeftShoulder, Joint.LeftArm, Joint.LeftForeArm, Joint.LeftHand),
    (Joint.RightShoulder, Joint.RightArm, Joint.RightForeArm, Joint.RightHand),
)
LEG_CHAINS: tuple[tuple[Joint, ...], tuple[Joint, ...]] = (
    (Joint.LeftUpLeg, Joint.LeftLeg, Joint.LeftFoot, Joint.LeftToeBase),
    (Joint.RightUpLeg, Joint.RightLeg, Joint.RightFoot, Joint.RightToeBase),
)

# End effectors as used by the seed papers' losses and the evaluations.
END_EFFECTORS: tuple[str, ...] = ("LeftHand", "RightHand", "LeftToeBase", "RightToeBase", "Head")


def default_canonical_skeleton() -> Skeleton:
    """A 1.7 m adult in a T-pose (Y up, facing +Z, left = +X), metres.

    Proportions follow common anthropometric tables; used for fixtures, the demo and as a
    fallback target. Real data carries its own offsets.
    """
    offsets = {
        "Hips": (0.0, 0.0, 0.0),
        "Spine": (0.0, 0.10, 0.0),
        "Spine1": (0.0, 0.12, 0.0),
        "Spine2": (0.0, 0.12, 0.0),
        "Neck": (0.0, 0.16, 0.0),
        "Head": (0.0, 0.10, 0.0),
        "LeftShoulder": (0.03, 0.12, 0.0),
        "LeftArm": (0.15, 0.0, 0.0),
        "LeftForeArm": (0.28, 0.0, 0.0),
        "LeftHand": (0.25, 0.0, 0.0),
        "RightShoulder": (-0.03, 0.12, 0.0),
        "RightArm": (-0.15, 0.0, 0.0),
        "RightForeArm": (-0.28, 0.0, 0.0),
        "RightHand": (-0.25, 0.0, 0.0),
        "LeftUpLeg": (0.09, -0.05, 0.0),
        "LeftLeg": (0.0, -0.42, 0.0),
        "LeftFoot": (0.0, -0.41, 0.0),
        "LeftToeBase": (0.0, -0.05, 0.13),
        "RightUpLeg": (-0.09, -0.05, 0.0),
        "RightLeg": (0.0, -0.42, 0.0),
        "RightFoot": (0.0, -0.41, 0.0),
        "RightToeBase": (0.0, -0.05, 0.13),
    }
    return Skeleton(
        CANONICAL_JOINTS,
        CANONICAL_PARENTS,
        np.array([offsets[n] for n in CANONICAL_JOINTS], dtype=np.float64),
    )
