"""One optimisation step of SAN with the paper's objective (Aberman et al. 2020, eq. 9):

    L_rec + λ_ltc L_ltc + λ_adv L_adv + λ_ee L_ee,   λ_ltc = 1, λ_adv = 0.25, λ_ee = 2.

Each batch comes from one source skeleton (robot_retarget.nn.dataset.WindowSampler with
``native``): its windows are encoded by that skeleton's own encoder, from the file's joints.

- L_rec: decoded onto the source's own proportions, the motion must be the source's. The paper
  compares a domain's decoder with its own input; we have one decoder (canonical) and the same
  window on the canonical skeleton, so a native source is reconstructed *across* topologies
  against its canonical version (a pairing the paper's data lacked). Rotations as 1 − ⟨q̂, q⟩²
  (sign-free), root-relative joint positions / height, root movement in heights per second.
  ``rotation``, ``position`` and ``root`` weigh those three inside L_rec.
- L_ltc: the retargeted motion, encoded again (by the canonical encoder: the target domain's),
  must give the latent it was decoded from.
- L_ee (eq. 8; ``ee_velocity``): end-effector velocities (toes, head, hands; world frame),
  each divided by the length of its chain from the root, equal on source and target.
- Optional (ours, off by default): the eval metrics as losses, as TDCN takes them
  (``--loss-weight bone=3`` etc.; tdcn_training.metric_losses).
- L_adv: least squares against the patch discriminator (robot_retarget.nn.patch_discriminator,
  as TDCN's: inputs normalised by height, so any performer's motion is real motion for any
  skeleton) on the samples whose target differs from the source.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from robot_retarget.nn.features import MotionFeatures, compute_features, skeleton_height
from robot_retarget.nn.losses import masked_mean
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.nn.models.optimizers import update_generator
from robot_retarget.nn.models.san import SAN
from robot_retarget.nn.models.tdcn_training import metric_losses
from robot_retarget.nn.patch_discriminator import (
    PatchDiscriminator,
    patch_discriminator_step,
    patch_inputs,
)
from robot_retarget.nn.retarget_losses import global_positions
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint
from robot_retarget.skeleton.canonical import END_EFFECTORS as CANONICAL_END_EFFECTORS

if TYPE_CHECKING:
    from robot_retarget.nn.models.optimizers import Optimizers

Tensor = torch.Tensor

END_EFFECTORS: tuple[int, ...] = tuple(int(Joint[name]) for name in CANONICAL_END_EFFECTORS)


@dataclass(frozen=True)
class SANLossWeights:
    """The paper's λ (eq. 9) and the weights inside our L_rec."""

    latent: float = 1.0
    adversarial: float = 0.25
    ee_velocity: float = 2.0
    rotation: float = 10.0
    position: float = 100.0
    root: float = 1.0
    grad_clip_norm: float = 25.0
    # The project's eval metrics as losses, as TDCN takes them (tdcn_training.metric_losses);
    # off by default: the paper's objective alone.
    effector: float = 0.0
    contact: float = 0.0
    bone: float = 0.0
    skate: float = 0.0
    denoise: float = 0.0


def chain_lengths(offsets: Tensor, joints: tuple[int, ...] = END_EFFECTORS) -> Tensor:
    """(B, E): the rest length of the chain from the root to each joint."""
    bone = torch.linalg.vector_norm(offsets, dim=-1)
    out = []
    for j in joints:
        total = bone.new_zeros(bone.shape[0])
        while j > 0:
            total = total + bone[:, j]
            j = CANONICAL_PARENTS[j]
        out.append(total)
    return torch.stack(out, dim=-1)


def reconstruction_error(
    out: MotionFeatures, src: MotionFeatures, height: Tensor, fps: float, w: SANLossWeights
) -> Tensor:
    """L_rec per sample (B,) (see the module docstring)."""
    dot = (out.local_quats * src.local_quats).sum(-1)
    rot = (1.0 - dot**2).mean((-1, -2))
    h = height[:, None, None, None]
    pos = (((out.local_pos - src.local_pos) / h) ** 2).sum(-1).mean((-1, -2))
    move = ((out.root_vel[..., :3] - src.root_vel[..., :3]) * fps / height[:, None, None]) ** 2
    turn = ((out.root_vel[..., 3] - src.root_vel[..., 3]) * fps) ** 2
    root = (move.sum(-1) + turn).mean(-1)
    return w.rotation * rot + w.position * pos + w.root * root


def effector_velocity_error(
    world_a: Tensor, offsets_a: Tensor, world_b: Tensor, offsets_b: Tensor, fps: float
) -> Tensor:
    """L_ee per sample (B,): ‖v_A / h_A − v_B / h_B‖² over end-effectors and frames."""
    ends = list(END_EFFECTORS)
    v_a = (world_a[:, 1:, ends] - world_a[:, :-1, ends]) * fps
    v_b = (world_b[:, 1:, ends] - world_b[:, :-1, ends]) * fps
    h_a = chain_lengths(offsets_a)[:, None, :, None]
    h_b = chain_lengths(offsets_b)[:, None, :, None]
    return ((v_a / h_a - v_b / h_b) ** 2).sum(-1).mean((-1, -2))


def san_training_step(
    model: SAN,
    disc: PatchDiscriminator,
    batch: RetargetBatch,
    optimizers: Optimizers,
    weights: SANLossWeights | None = None,
    fps: float = 30.0,
) -> dict[str, float]:
    """One generator step and one discriminator step; returns the loss terms."""
    w = weights or SANLossWeights()
    model.train()
    disc.train()
    src_off, tgt_off = batch.src_offsets, batch.tgt_offsets
    h_a = skeleton_height(src_off)
    src = compute_features(batch.src_local_quats, batch.src_root_pos, src_off)
    init, yaw0 = batch.src_root_pos[:, 0], src.yaw[:, 0]
    if batch.native_domain is not None and batch.native_quats is not None:
        assert batch.native_offsets is not None  # RetargetBatch checks they come together
        latent = model.encode(
            batch.native_domain,
            src.local_quats[:, :, 0],
            src.root_vel,
            h_a,
            batch.native_quats,
            batch.native_offsets,
        )
    else:
        latent = model.encode_canonical(src, src_off)
    out_a = model.output(model.decode(latent, src_off), init, yaw0, src_off)
    rec = reconstruction_error(out_a.features, src, h_a, fps, w)

    out_b = model.output(model.decode(latent, tgt_off), init, yaw0, tgt_off)
    fb = out_b.features
    world_src = global_positions(src.local_pos, batch.src_root_pos, src.yaw)
    world_b = global_positions(fb.local_pos, out_b.root_pos, fb.yaw)
    ee = w.ee_velocity * effector_velocity_error(world_src, src_off, world_b, tgt_off, fps)
    ltc = w.latent * ((model.encode_canonical(fb, tgt_off) - latent) ** 2).mean((1, 2, 3))
    other = ~batch.same_skeleton.to(torch.bool)
    lsgan = ((disc(patch_inputs(fb.local_pos, fb.root_vel, tgt_off)) - 1.0) ** 2).mean(-1)
    adversarial = w.adversarial * torch.where(other, lsgan, torch.zeros_like(lsgan))
    extra = metric_losses(model, batch, src, out_b, w, fps)
    total = (rec + ee + ltc + adversarial + sum(extra.values())).mean()
    update_generator(optimizers, model, total, w.grad_clip_norm)

    losses = {
        "total": float(total.detach()),
        "reconstruction": float(rec.detach().mean()),
        "ee_velocity": float(ee.detach().mean()),
        "latent": float(ltc.detach().mean()),
        "adversarial": masked_mean(lsgan, other),
        **{name: float(term.detach().mean()) for name, term in extra.items()},
    }
    d_opt = optimizers.discriminator
    if d_opt is not None and bool(other.any()):
        losses.update(patch_discriminator_step(disc, d_opt, src, src_off, fb, tgt_off, other))
    return losses
