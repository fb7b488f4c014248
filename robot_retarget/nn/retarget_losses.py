"""Geometric retargeting losses: the ``eval`` metrics, made differentiable (torch).

No ground truth exists for "this person's motion on that body", so the residual model is
trained on what the evaluation measures against the source (robot_retarget.evaluation.metrics
and foot_contact), per sample (B,), frames averaged:

- :func:`effector_loss`: hands and feet relative to the root, in arm / leg lengths;
- :func:`contact_loss`: hand–hand, hand–head, hand–hip and foot–foot distances, in limb lengths;
- :func:`bone_direction_loss`: angle between source and target bone directions (radians);
- :func:`foot_skate_loss`: the target's horizontal foot speed while the source's foot is
  planted (leg lengths per second);
- :func:`denoising_loss`: joint-position error of a denoised pose against the clean one
  (height-normalised, × 10³ as the metric).

Norms are smoothed at zero (√(x² + ε²) − ε) so their gradients stay finite when the error
vanishes, e.g. for a target that is its own source. Two differences from the metrics, both from
training on windows: a foot's "lowest point" for contact detection is the window's, not the
clip's, and a window without contact adds 0 skate (the metric skips such clips as NaN).
"""

from __future__ import annotations

import torch

from robot_retarget.evaluation.foot_contact import (
    CONTACT_HEIGHT_LEGS,
    CONTACT_SPEED_LEGS_S,
    FOOT_JOINTS,
)
from robot_retarget.evaluation.metrics import CONTACT_PAIRS, FEET, HANDS
from robot_retarget.nn.features import skeleton_height, yaw_rotate
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint

Tensor = torch.Tensor

_EPS = 1e-4
_MIN_BONE_M = 1e-6


def _smooth_norm(v: Tensor) -> Tensor:
    return torch.sqrt((v * v).sum(dim=-1) + _EPS * _EPS) - _EPS


def _unit(v: Tensor) -> Tensor:
    return v / torch.linalg.vector_norm(v, dim=-1, keepdim=True).clamp_min(_MIN_BONE_M)


def _smooth_abs(x: Tensor) -> Tensor:
    return torch.sqrt(x * x + _EPS * _EPS) - _EPS


def limb_lengths(offsets: Tensor) -> tuple[Tensor, Tensor]:
    """Arm (upper arm + forearm) and leg (thigh + shin) lengths (B,), both sides averaged."""
    n = torch.linalg.vector_norm(offsets, dim=-1)
    arm = 0.5 * (n[:, Joint.LeftForeArm] + n[:, Joint.LeftHand]) + 0.5 * (
        n[:, Joint.RightForeArm] + n[:, Joint.RightHand]
    )
    leg = 0.5 * (n[:, Joint.LeftLeg] + n[:, Joint.LeftFoot]) + 0.5 * (
        n[:, Joint.RightLeg] + n[:, Joint.RightFoot]
    )
    return arm, leg


def _effectors(pos: Tensor, offsets: Tensor) -> Tensor:
    """Hands and feet relative to the root in limb lengths, (B, T, 4, 3)."""
    arm, leg = limb_lengths(offsets)
    scale = torch.stack([arm, arm, leg, leg], dim=-1)[:, None, :, None]
    rel = pos[:, :, list(HANDS + FEET)] - pos[:, :, :1]
    return rel / scale


def effector_loss(
    src_pos: Tensor, src_offsets: Tensor, tgt_pos: Tensor, tgt_offsets: Tensor
) -> Tensor:
    """Mean distance between source and target effectors (limb lengths), per sample (B,).

    Positions (B, T, J, 3) in the same (heading) frame, e.g. the models' local pose features.
    """
    diff = _effectors(tgt_pos, tgt_offsets) - _effectors(src_pos, src_offsets)
    return _smooth_norm(diff).mean(dim=(1, 2))


def _contacts(pos: Tensor, offsets: Tensor) -> Tensor:
    arm, leg = limb_lengths(offsets)
    limbs = {"arm": arm[:, None], "leg": leg[:, None]}
    cols = [
        torch.linalg.vector_norm(pos[:, :, a] - pos[:, :, b], dim=-1) / limbs[limb]
        for a, b, limb in CONTACT_PAIRS
    ]
    return torch.stack(cols, dim=-1)


def contact_loss(
    src_pos: Tensor, src_offsets: Tensor, tgt_pos: Tensor, tgt_offsets: Tensor
) -> Tensor:
    """Mean |d_target − d_source| of the contact pairs (limb lengths), per sample (B,)."""
    diff = _contacts(tgt_pos, tgt_offsets) - _contacts(src_pos, src_offsets)
    return _smooth_abs(diff).mean(dim=(1, 2))


def bone_direction_loss(
    src_pos: Tensor, src_offsets: Tensor, tgt_pos: Tensor, tgt_offsets: Tensor
) -> Tensor:
    """Mean angle (rad) between source and target bone directions, per sample (B,).

    Bones of zero length on either skeleton are skipped, as in the metric.
    """
    parents = torch.tensor(CANONICAL_PARENTS[1:], device=src_pos.device)
    children = torch.arange(1, len(CANONICAL_PARENTS), device=src_pos.device)
    valid = (torch.linalg.vector_norm(src_offsets[:, 1:], dim=-1) > _MIN_BONE_M) & (
        torch.linalg.vector_norm(tgt_offsets[:, 1:], dim=-1) > _MIN_BONE_M
    )
    bs = _unit(src_pos[:, :, children] - src_pos[:, :, parents])
    bt = _unit(tgt_pos[:, :, children] - tgt_pos[:, :, parents])
    cross = _smooth_norm(torch.linalg.cross(bs, bt, dim=-1))
    angle = torch.atan2(cross, (bs * bt).sum(dim=-1))  # (B, T, bones)
    w = valid[:, None].to(angle).expand_as(angle)
    return (angle * w).sum(dim=(1, 2)) / w.sum(dim=(1, 2)).clamp_min(1.0)


def global_positions(local_pos: Tensor, root_pos: Tensor, yaw: Tensor) -> Tensor:
    """World joint positions (B, T, J, 3) from local pose features, root path and heading."""
    return root_pos[:, :, None] + yaw_rotate(local_pos, yaw[..., None])


def foot_contacts(world_pos: Tensor, fps: float, offsets: Tensor) -> Tensor:
    """Contact flags (B, T, 4) of FOOT_JOINTS, as robot_retarget.evaluation.foot_contact."""
    _, leg = limb_lengths(offsets)
    feet = world_pos[:, :, list(FOOT_JOINTS)]
    speed = _horizontal_speed(feet, fps, smooth=False)
    height = feet[..., 1] - feet[..., 1].amin(dim=1, keepdim=True)
    leg = leg[:, None, None]
    return (speed < CONTACT_SPEED_LEGS_S * leg) & (height < CONTACT_HEIGHT_LEGS * leg)


def _horizontal_speed(points: Tensor, fps: float, smooth: bool = True) -> Tensor:
    """Horizontal speed (B, T, K) of points (B, T, K, 3); frame 0 copies frame 1. ``smooth``:
    a gradient-safe norm (for losses), else the exact one (for contact flags)."""
    step_xz = (points[:, 1:] - points[:, :-1])[..., [0, 2]]
    norm = _smooth_norm(step_xz) if smooth else torch.linalg.vector_norm(step_xz, dim=-1)
    step = norm * fps
    return torch.cat([step[:, :1], step], dim=1)


def foot_skate_loss(world_pos: Tensor, contacts: Tensor, fps: float, offsets: Tensor) -> Tensor:
    """Mean horizontal foot speed (leg lengths/s) over the contact frames, per sample (B,);
    0 for a sample without contact."""
    _, leg = limb_lengths(offsets)
    speed = _horizontal_speed(world_pos[:, :, list(FOOT_JOINTS)], fps) / leg[:, None, None]
    w = contacts.to(speed)
    return (speed * w).sum(dim=(1, 2)) / w.sum(dim=(1, 2)).clamp_min(1.0)


def denoising_loss(pos: Tensor, clean_pos: Tensor, offsets: Tensor) -> Tensor:
    """‖(p_j − p̂_j) / height‖² × 10³ averaged over frames and joints, per sample (B,)."""
    h = skeleton_height(offsets)[:, None, None, None]
    return (((pos - clean_pos) / h) ** 2).sum(dim=-1).mean(dim=(1, 2)) * 1e3
