"""What the positions → rotations solve works with: which joints take a triad instead of a bone
direction, where their axes come from, and its tolerances. Free of casadi and torch, so the live
path's solve (``robot_retarget.sources.from_positions``) and its torch twin for training
(``robot_retarget.nn.positions_to_rotations``) read one definition."""

from __future__ import annotations

from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint

EPS = 1e-9  # a shorter axis or bone counts as zero (m)
MIN_SECONDARY_M = 1e-3  # rest axes shorter than this are not used
# Joints whose rotation comes from a triad: (joint, primary child point, secondary (left, right)).
# Spine2 uses its own children (the shoulder joints), which move rigidly with it; when a
# skeleton puts both shoulder joints at one point, the arms' line is used instead.
TRIADS: dict[int, tuple[int, tuple[int, int]]] = {
    Joint.Hips: (Joint.Spine, (Joint.LeftUpLeg, Joint.RightUpLeg)),
    Joint.Spine2: (Joint.Neck, (Joint.LeftShoulder, Joint.RightShoulder)),
}
TRIAD_FALLBACK: dict[int, tuple[int, int]] = {Joint.Spine2: (Joint.LeftArm, Joint.RightArm)}
# The primary axis may come from a joint further up when the nearest one sits on the joint
# itself (CMU MotionBuilder skeletons put Spine at the Hips: a zero-length axis would leave the
# Hips unrotated, and every pose turned by the performer's heading, up to 90° off).
PRIMARY_CHAIN: dict[int, tuple[int, ...]] = {
    Joint.Hips: (Joint.Spine, Joint.Spine1, Joint.Spine2, Joint.Neck),
    Joint.Spine2: (Joint.Neck, Joint.Head),
}


def single_children(parents: tuple[int, ...] = CANONICAL_PARENTS) -> dict[int, int]:
    """``{joint: its child}`` for the joints with exactly one child: their bone direction is
    what the solve points."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        if p >= 0:
            children.setdefault(p, []).append(j)
    return {j: c[0] for j, c in children.items() if len(c) == 1}
