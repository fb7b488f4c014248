"""Loss terms of NKN (eq. 10–16) and PMnet (eq. 8–11), per sample.

Every function returns one value per sample (B,), so a training step can mask samples (NKN's
B = A case) before averaging. Reduction, where the papers write ‖·‖²₂ over a whole sequence:
squared errors are *summed over features/joints and averaged over frames* (and the batch mean
is taken by the caller). This keeps the papers' relative weights (β, λ, ω, λ_p, λ_m, λ_r) meaning
"per frame" and independent of the window length.

GAN terms take discriminator logits: log D = log σ(ℓ) = −softplus(−ℓ) and
log(1 − D) = −softplus(ℓ).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch.nn import functional as nnf

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import integrate_root, yaw_quat
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, END_EFFECTORS, Joint

Tensor = torch.Tensor

TWIST_ALPHA_RAD = math.radians(100.0)
"""NKN's and PMnet's twist threshold α = 100°."""

_MIN_BONE_M = 1e-6

END_EFFECTOR_JOINTS: tuple[int, ...] = tuple(int(Joint[name]) for name in END_EFFECTORS)


def twist_axes(offsets: Tensor, parents: Sequence[int] = CANONICAL_PARENTS) -> Tensor:
    """Bone axis (B, J, 3) about which each joint's twist is measured, unit, in its frame.

    A joint's rotation swings the bone to its (first non-zero) child; the twist about that
    bone changes no position, which is why the papers penalise it. Leaves use their own
    offset from the parent (the same bone direction at rest), zero-length chains fall back to
    the up axis. The root's entry is unused (the root orientation is free).
    """
    j = len(parents)
    norms = torch.linalg.vector_norm(offsets, dim=-1)  # (B, J)
    up = torch.zeros_like(offsets[:, 0])
    up[:, 1] = 1.0
    axes = []
    for i in range(j):
        children = [c for c in range(j) if parents[c] == i]
        # torch.where keeps the last match: least preferred first, the first child last.
        axis = up
        for c in [i, *children[::-1]]:
            ok = (norms[:, c] > _MIN_BONE_M)[:, None]
            axis = torch.where(ok, offsets[:, c] / norms[:, c, None].clamp_min(_MIN_BONE_M), axis)
        axes.append(axis)
    return torch.stack(axes, dim=1)


def twist_loss(
    local_quats: Tensor,
    offsets: Tensor,
    alpha_rad: float = TWIST_ALPHA_RAD,
    parents: Sequence[int] = CANONICAL_PARENTS,
) -> Tensor:
    """‖max(0, |twist| − α)‖² per sample (B,): joints summed, frames averaged, root excluded.

    ``local_quats`` (B, T, J, 4), ``offsets`` (B, J, 3) of the skeleton they drive.
    """
    axes = twist_axes(offsets, parents)[:, None, 1:]
    angle = qt.twist_angle(local_quats[..., 1:, :], axes)
    excess = nnf.relu(angle.abs() - alpha_rad)
    return (excess**2).sum(dim=-1).mean(dim=-1)


def squared_error(pred: Tensor, target: Tensor) -> Tensor:
    """Σ over features of squared error, averaged over frames: (B, T, …) → (B,)."""
    diff = (pred - target) ** 2
    return diff.flatten(2).sum(dim=-1).mean(dim=-1)


def velocity_smoothing_loss(root_vel: Tensor) -> Tensor:
    """NKN's S: ‖v_{t+1} − v_t‖² per sample (B,) for root velocities (B, T, 4)."""
    return squared_error(root_vel[:, 1:], root_vel[:, :-1])


def end_effector_weights(
    weight: float = 2.0,
    parents: Sequence[int] = CANONICAL_PARENTS,
    end_effectors: Sequence[int] = END_EFFECTOR_JOINTS,
) -> Tensor:
    """Per-joint weights (J,): ``weight`` on the end-effector chains, 1 on the trunk.

    PMnet doubles "joints that affect the end-effector positions". Every joint of a tree lies
    on some root-to-effector path, so we read it as each effector's own chain: the joints from
    the effector up to (excluding) the nearest branching joint — Shoulder…Hand, UpLeg…ToeBase,
    Neck…Head — leaving the shared trunk (Hips, Spine, Spine1, Spine2) at 1.
    """
    j = len(parents)
    child_count = [sum(1 for p in parents if p == i) for i in range(j)]
    w = torch.ones(j)
    for e in end_effectors:
        n = int(e)
        while n > 0:
            w[n] = weight
            n = parents[n]
            if child_count[n] > 1:
                break
    return w


def reconstruction_loss(pred_pos: Tensor, target_pos: Tensor, joint_weights: Tensor) -> Tensor:
    """PMnet's L_recon per sample (B,): Σ_j w_j ‖p_j − p̂_j‖², frames averaged. (B, T, J, 3)."""
    err = ((pred_pos - target_pos) ** 2).sum(dim=-1) * joint_weights.to(pred_pos)
    return err.sum(dim=-1).mean(dim=-1)


def perceptual_pose_loss(phi_a: Tensor, phi_b: Tensor) -> Tensor:
    """PMnet's ‖φ_A − φ_B‖² per sample (B,) (λ_p applied by the caller)."""
    return squared_error(phi_b, phi_a)


def mean_point_trajectory(local_pos: Tensor, root_vel: Tensor, scale: Tensor) -> Tensor:
    """PMnet's scale-normalised mean-point trajectory m̄_t / S, (B, T, 3).

    m̄_t is the mean of all joint positions. The window's absolute place and heading carry no
    information (and the target's start is borrowed from the source), so the trajectory is
    expressed relative to the first frame's root position, in its heading frame: only the
    root velocities and the local pose enter.
    """
    b = root_vel.shape[0]
    zeros = root_vel.new_zeros(b)
    root, yaw = integrate_root(root_vel, root_vel.new_zeros(b, 3), zeros)
    mean_local = local_pos.mean(dim=-2)
    traj = root + qt.rotate(yaw_quat(yaw), mean_local)
    return traj / scale[:, None, None]


def discriminator_loss(real_logits: Tensor, fake_logits: Tensor) -> Tensor:
    """−[log D(real) + log(1 − D(fake))] per sample (B,)."""
    return nnf.softplus(-real_logits) + nnf.softplus(fake_logits)


def generator_adversarial_loss(fake_logits: Tensor) -> Tensor:
    """The papers' generator term log(1 − D(fake)) per sample (B,), to be minimised.

    (The saturating form, as written in NKN eq. 13 and PMnet eq. 10; it is ≤ 0.)
    """
    return -nnf.softplus(fake_logits)


def masked_mean(values: Tensor, mask: Tensor) -> float:
    """Mean of ``values`` (detached) where ``mask`` holds; 0 when it holds nowhere (a loss
    term logged for the samples it applies to)."""
    if not bool(mask.any()):
        return 0.0
    return float(values.detach()[mask].mean())
