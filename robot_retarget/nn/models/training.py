"""One optimisation step of NKN or PMnet with the papers' losses and weights.

A ``train`` command only loops: draw a :class:`RetargetBatch`, call :func:`training_step`, log
the returned losses. Both papers train with Adam, learning rate 1e-4, for generator and
discriminator (robot_retarget.nn.models.optimizers.make_optimizers).

NKN (eq. 10): cycle C + R + λ J + ω S with R the square loss ‖x̂_B − x_A‖² where B = A and
β log(1 − r_B) otherwise (β = 0.001), twist J (α = 100°, λ = 10), smoothing S (ω = 0.01);
generator gradients clipped to global norm 25; the discriminator is not updated while its
mean probability of "real" on retargeted motion is below 0.3 (appendix E).

PMnet (eq. 12): reconstruction (end-effector chains ×2) + λ_p perceptual pose (5) + λ_m
motion discrimination (2) + λ_r rotation constraint (10, α = 100°).

Residual (ours, robot_retarget.nn.models.residual): no discriminator. The clean source goes
through the model for the geometric losses of robot_retarget.nn.retarget_losses (effectors,
contacts, bone directions, foot skate), a root-velocity loss against copy-scaled's and PMnet's
rotation constraint (λ_r = 10, α = 100°); a copy corrupted as in the denoising test goes through
it for a supervised denoising loss (denoised source pose against the clean one, and its root
path against the clean pass's) and an optional consistency loss (its whole output against the
clean input's, the denoising metric; off by default). Adam, gradients
clipped to norm 25.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TypeVar

import torch
from torch import nn

from robot_retarget.nn.corruption import CorruptionRanges, corrupt_batch
from robot_retarget.nn.discriminators import NKNDiscriminator, PMnetDiscriminator
from robot_retarget.nn.features import (
    MotionFeatures,
    compute_features,
    local_positions,
    skeleton_height,
)
from robot_retarget.nn.features import pmnet_scale as scale_of
from robot_retarget.nn.live_noise import corrupt_live
from robot_retarget.nn.losses import (
    TWIST_ALPHA_RAD,
    discriminator_loss,
    end_effector_weights,
    generator_adversarial_loss,
    masked_mean,
    mean_point_trajectory,
    perceptual_pose_loss,
    reconstruction_loss,
    squared_error,
    twist_loss,
    velocity_smoothing_loss,
)
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.nn.models.nkn import NKN
from robot_retarget.nn.models.optimizers import (
    Optimizers,
    update_generator,
)
from robot_retarget.nn.models.pmnet import PMnet
from robot_retarget.nn.models.residual import ResidualRetargeter
from robot_retarget.nn.models.san import SAN
from robot_retarget.nn.models.san_training import SANLossWeights, san_training_step
from robot_retarget.nn.models.tdcn import TDCN
from robot_retarget.nn.models.tdcn_training import TDCNLossWeights, tdcn_training_step
from robot_retarget.nn.patch_discriminator import PatchDiscriminator
from robot_retarget.nn.retarget_losses import (
    bone_direction_loss,
    contact_loss,
    denoising_loss,
    effector_loss,
    foot_contacts,
    foot_skate_loss,
    global_positions,
)

Tensor = torch.Tensor

DEFAULT_FPS = 30.0


@dataclass(frozen=True)
class NKNLossWeights:
    """NKN's published hyper-parameters (section 4.2, appendix E)."""

    beta: float = 0.001
    twist_lambda: float = 10.0
    twist_alpha_rad: float = TWIST_ALPHA_RAD
    smoothing_omega: float = 0.01
    grad_clip_norm: float = 25.0
    disc_min_fake_prob: float = 0.3


@dataclass(frozen=True)
class PMnetLossWeights:
    """PMnet's published hyper-parameters (section 3.3)."""

    lambda_pose: float = 5.0
    lambda_motion: float = 2.0
    lambda_rot: float = 10.0
    twist_alpha_rad: float = TWIST_ALPHA_RAD
    end_effector_weight: float = 2.0


def _detached(f: MotionFeatures) -> MotionFeatures:
    return MotionFeatures(
        local_pos=f.local_pos.detach(),
        root_vel=f.root_vel.detach(),
        local_quats=f.local_quats.detach(),
        yaw=f.yaw.detach(),
    )


def _discriminator_optimizer(optimizers: Optimizers) -> torch.optim.Optimizer:
    if optimizers.discriminator is None:
        raise ValueError("this model trains against a discriminator: build its optimiser too")
    return optimizers.discriminator


def _discriminator_update(
    disc: nn.Module, opt: torch.optim.Optimizer, real: Tensor, fake: Tensor, mask: Tensor
) -> tuple[float, float]:
    """Loss and mean P(real | fake) on the masked samples (the update is the caller's call)."""
    opt.zero_grad(set_to_none=True)
    real_logits = disc(real)
    fake_logits = disc(fake)
    loss = discriminator_loss(real_logits, fake_logits)[mask].mean()
    fake_prob = torch.sigmoid(fake_logits.detach())[mask].mean()
    loss.backward()  # type: ignore[no-untyped-call]
    return float(loss.detach()), float(fake_prob)


def nkn_training_step(
    model: NKN,
    disc: NKNDiscriminator,
    batch: RetargetBatch,
    optimizers: Optimizers,
    weights: NKNLossWeights | None = None,
) -> dict[str, float]:
    """One adversarial cycle-consistency step (NKN eq. 10); returns the loss terms."""
    w = weights or NKNLossWeights()
    model.train()
    disc.train()
    src = compute_features(batch.src_local_quats, batch.src_root_pos, batch.src_offsets)
    init = batch.src_root_pos[:, 0]
    out_b = model.retarget_features(src, init, batch.src_offsets, batch.tgt_offsets)
    out_a = model.retarget_features(out_b.features, init, batch.tgt_offsets, batch.src_offsets)

    same = batch.same_skeleton.to(torch.bool)
    cycle = squared_error(out_a.features.x, src.x)
    square = squared_error(out_b.features.x, src.x)
    fake_logits = disc(NKNDiscriminator.inputs(out_b.features, batch.tgt_offsets))
    adversarial = w.beta * generator_adversarial_loss(fake_logits)
    r_term = torch.where(same, square, adversarial)
    twist = w.twist_lambda * (
        twist_loss(out_b.features.local_quats, batch.tgt_offsets, w.twist_alpha_rad)
        + twist_loss(out_a.features.local_quats, batch.src_offsets, w.twist_alpha_rad)
    )
    smooth = w.smoothing_omega * (
        velocity_smoothing_loss(out_b.features.root_vel)
        + velocity_smoothing_loss(out_a.features.root_vel)
    )
    total = (cycle + r_term + twist + smooth).mean()
    update_generator(optimizers, model, total, w.grad_clip_norm)

    losses = {
        "total": float(total.detach()),
        "cycle": float(cycle.detach().mean()),
        "square": masked_mean(square, same),
        "adversarial": masked_mean(adversarial, ~same),
        "twist": float(twist.detach().mean()),
        "smoothing": float(smooth.detach().mean()),
    }
    other = ~same
    if bool(other.any()) and batch.real_local_quats is not None and batch.real_root_pos is not None:
        real = compute_features(batch.real_local_quats, batch.real_root_pos, batch.tgt_offsets)
        d_loss, fake_prob = _discriminator_update(
            disc,
            _discriminator_optimizer(optimizers),
            NKNDiscriminator.inputs(real, batch.tgt_offsets),
            NKNDiscriminator.inputs(_detached(out_b.features), batch.tgt_offsets),
            other,
        )
        # Balancing (appendix E): let the generator catch up while the discriminator wins.
        updated = fake_prob >= w.disc_min_fake_prob
        if updated:
            _discriminator_optimizer(optimizers).step()
        losses.update(discriminator=d_loss, disc_fake_prob=fake_prob, disc_updated=float(updated))
    return losses


def pmnet_training_step(
    model: PMnet,
    disc: PMnetDiscriminator,
    batch: RetargetBatch,
    optimizers: Optimizers,
    weights: PMnetLossWeights | None = None,
) -> dict[str, float]:
    """One PMnet step (eq. 12) and one discriminator step; returns the loss terms."""
    w = weights or PMnetLossWeights()
    model.train()
    disc.train()
    src = compute_features(batch.src_local_quats, batch.src_root_pos, batch.src_offsets)
    out = model.retarget_features(
        src, batch.src_root_pos[:, 0], batch.src_offsets, batch.tgt_offsets
    )
    q_a = out.extras["q_a"]
    phi_a = out.extras["phi_a"]

    joint_w = end_effector_weights(w.end_effector_weight).to(src.local_pos)
    recon = reconstruction_loss(local_positions(q_a, batch.src_offsets), src.local_pos, joint_w)
    # As published: the perceptual loss trains the encoder on both sides. Freezing it there
    # (φ_A constant, φ_B through detached weights) measured worse: bone direction 32.1° vs
    # 19.1°, effector error 0.362 vs 0.254 (3000 vs 4500 steps, otherwise the same command).
    phi_b = model.encode_pose(out.features.pose_flat)
    pose = w.lambda_pose * perceptual_pose_loss(phi_a, phi_b)
    fake_traj = mean_point_trajectory(
        out.features.local_pos, out.features.root_vel, scale_of(batch.tgt_offsets)
    )
    motion = w.lambda_motion * generator_adversarial_loss(disc(fake_traj))
    rot = w.lambda_rot * (
        twist_loss(q_a, batch.src_offsets, w.twist_alpha_rad)
        + twist_loss(out.features.local_quats, batch.tgt_offsets, w.twist_alpha_rad)
    )
    total = (recon + pose + motion + rot).mean()
    optimizers.generator.zero_grad(set_to_none=True)
    total.backward()  # type: ignore[no-untyped-call]
    optimizers.generator.step()

    real_traj = mean_point_trajectory(src.local_pos, src.root_vel, scale_of(batch.src_offsets))
    everyone = torch.ones_like(batch.same_skeleton, dtype=torch.bool)
    d_opt = _discriminator_optimizer(optimizers)
    d_loss, fake_prob = _discriminator_update(disc, d_opt, real_traj, fake_traj.detach(), everyone)
    d_opt.step()
    return {
        "total": float(total.detach()),
        "reconstruction": float(recon.detach().mean()),
        "pose": float(pose.detach().mean()),
        "motion": float(motion.detach().mean()),
        "rotation": float(rot.detach().mean()),
        "discriminator": d_loss,
        "disc_fake_prob": fake_prob,
    }


@dataclass(frozen=True)
class ResidualLossWeights:
    """Weights of the residual model's losses (ours; see the module docstring).

    The geometric terms are in the metrics' units (limb lengths, radians, leg lengths per
    second); ``denoise``, ``consistency`` and ``root`` are height-normalised squared errors
    × 10³, the denoising metric's unit.
    """

    effector: float = 1.0
    contact: float = 1.0
    bone: float = 3.0
    skate: float = 0.1
    denoise: float = 3.0
    # The output-level consistency term pulls the pose correction towards ignoring its input:
    # at 0.5 (1000 steps) it cost 0.025 limb lengths of effector error and 1.8° of bone
    # direction to bring the denoising error from 1.52 to 0.89 (copy-scaled: 3.46), so it is
    # off by default.
    consistency: float = 0.0
    root: float = 1.0
    lambda_rot: float = 10.0
    twist_alpha_rad: float = TWIST_ALPHA_RAD
    grad_clip_norm: float = 25.0


def residual_training_step(
    model: ResidualRetargeter,
    batch: RetargetBatch,
    optimizers: Optimizers,
    weights: ResidualLossWeights | None = None,
    corruption: CorruptionRanges | None = None,
    fps: float = DEFAULT_FPS,
) -> dict[str, float]:
    """One step of the residual model: the clean source through the model for the geometric
    losses, a corrupted copy for the denoising losses (see the module docstring)."""
    w = weights or ResidualLossWeights()
    model.train()
    src_off, tgt_off = batch.src_offsets, batch.tgt_offsets
    init = batch.src_root_pos[:, 0]
    h_src = skeleton_height(src_off)
    h_tgt = skeleton_height(tgt_off)
    clean = compute_features(batch.src_local_quats, batch.src_root_pos, src_off)
    out = model.retarget_features(clean, init, src_off, tgt_off)
    pos_b = out.features.local_pos

    effector = effector_loss(clean.local_pos, src_off, pos_b, tgt_off)
    contact = contact_loss(clean.local_pos, src_off, pos_b, tgt_off)
    bone = bone_direction_loss(clean.local_pos, src_off, pos_b, tgt_off)
    planted = foot_contacts(
        global_positions(clean.local_pos, batch.src_root_pos, clean.yaw), fps, src_off
    )
    world_b = global_positions(pos_b, out.root_pos, out.features.yaw)
    skate = foot_skate_loss(world_b, planted, fps, tgt_off)
    rot = w.lambda_rot * twist_loss(out.features.local_quats, tgt_off, w.twist_alpha_rad)
    # The root should move as copy-scaled's: F_v may smooth, not lag or drift.
    scaled = clean.root_vel[..., :3] / h_src[:, None, None]
    vel_err = (out.features.root_vel[..., :3] / h_tgt[:, None, None] - scaled) ** 2
    root = vel_err.sum(-1).mean(-1) * 1e3

    ranges = corruption or CorruptionRanges()
    noisy_q, noisy_root = corrupt_batch(batch.src_local_quats, batch.src_root_pos, h_src, ranges)
    if ranges.live_share > 0.0:
        # A share of the samples as a live position sender delivers them instead.
        live = torch.nonzero(torch.rand(noisy_q.shape[0]) < ranges.live_share).flatten()
        if live.numel():
            live = live.to(noisy_q.device)
            live_q, live_root = corrupt_live(
                batch.src_local_quats[live],
                batch.src_root_pos[live],
                src_off[live],
                h_src[live],
                ranges.live,
                fps,
            )
            noisy_q, noisy_root = noisy_q.clone(), noisy_root.clone()
            noisy_q[live], noisy_root[live] = live_q, live_root
    noisy = compute_features(noisy_q, noisy_root, src_off)
    out_noisy = model.retarget_features(noisy, noisy_root[:, 0], src_off, tgt_off)
    denoise = denoising_loss(out_noisy.extras["pos_denoised"], clean.local_pos, src_off)
    # The root filter learns to smooth a jittery root: the noisy pass's path against the clean
    # pass's, each relative to its own first frame (its noise cannot be known).
    path_noisy = out_noisy.root_pos - out_noisy.root_pos[:, :1]
    path_clean = (out.root_pos - out.root_pos[:, :1]).detach()
    root_noise = (((path_noisy - path_clean) / h_tgt[:, None, None]) ** 2).sum(-1).mean(-1) * 1e3
    consistency = torch.zeros_like(denoise)
    if w.consistency > 0.0:
        # The denoising metric itself: the output for noisy input against the clean input's.
        world_noisy = global_positions(
            out_noisy.features.local_pos, out_noisy.root_pos, out_noisy.features.yaw
        )
        consistency = denoising_loss(world_noisy, world_b.detach(), tgt_off)
    total = (
        w.effector * effector
        + w.contact * contact
        + w.bone * bone
        + w.skate * skate
        + w.denoise * (denoise + root_noise)
        + w.consistency * consistency
        + w.root * root
        + rot
    ).mean()
    update_generator(optimizers, model, total, w.grad_clip_norm)
    return {
        "total": float(total.detach()),
        "effector": float(effector.detach().mean()),
        "contact": float(contact.detach().mean()),
        "bone": float(bone.detach().mean()),
        "skate": float(skate.detach().mean()),
        "denoise": float(denoise.detach().mean()),
        "root_noise": float(root_noise.detach().mean()),
        "consistency": float(consistency.detach().mean()),
        "root": float(root.detach().mean()),
        "rotation": float(rot.detach().mean()),
    }


_W = TypeVar(
    "_W", NKNLossWeights, PMnetLossWeights, ResidualLossWeights, TDCNLossWeights, SANLossWeights
)


def loss_weights(defaults: _W, overrides: Mapping[str, float] | None) -> _W:
    """``defaults`` with ``overrides`` applied; raises ValueError naming an unknown key."""
    if not overrides:
        return defaults
    allowed = [f.name for f in dataclasses.fields(defaults)]
    unknown = sorted(set(overrides) - set(allowed))
    if unknown:
        raise ValueError(
            f"unknown loss weight(s) {unknown} for {type(defaults).__name__}; "
            f"allowed: {', '.join(allowed)}"
        )
    bad = {
        k: v
        for k, v in overrides.items()
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0
    }
    if bad:
        raise ValueError(f"loss weights must be finite numbers ≥ 0, got {bad}")
    return dataclasses.replace(defaults, **{k: float(v) for k, v in overrides.items()})


def check_loss_weights(model_name: str, overrides: Mapping[str, float] | None) -> None:
    """Raise ValueError now (before any data loads) if ``overrides`` names an unknown weight."""
    if model_name == "nkn":
        loss_weights(NKNLossWeights(), overrides)
    elif model_name == "pmnet":
        loss_weights(PMnetLossWeights(), overrides)
    elif model_name == "tdcn":
        loss_weights(TDCNLossWeights(), overrides)
    elif model_name == "san":
        loss_weights(SANLossWeights(), overrides)
    else:
        loss_weights(ResidualLossWeights(), overrides)


def training_step(
    model: RetargetModel,
    disc: nn.Module | None,
    batch: RetargetBatch,
    optimizers: Optimizers,
    fps: float = DEFAULT_FPS,
    weights: Mapping[str, float] | None = None,
    *,
    live_noise: float = 0.0,
) -> dict[str, float]:
    """One step of whichever trainable model this is: its default loss weights (the papers'
    for NKN and PMnet) with ``weights`` overriding some of them; ``live_noise`` (residual
    model): the share of denoising samples corrupted as a live position sender's."""
    if isinstance(model, ResidualRetargeter) and disc is None:
        w_res = loss_weights(ResidualLossWeights(), weights)
        corruption = CorruptionRanges(live_share=live_noise)
        return residual_training_step(model, batch, optimizers, w_res, corruption, fps=fps)
    if live_noise > 0.0:
        raise ValueError(
            f"--live-noise trains the residual model's denoiser; {type(model).__name__} has none"
        )
    if isinstance(model, NKN) and isinstance(disc, NKNDiscriminator):
        w_nkn = loss_weights(NKNLossWeights(), weights)
        return nkn_training_step(model, disc, batch, optimizers, w_nkn)
    if isinstance(model, PMnet) and isinstance(disc, PMnetDiscriminator):
        w_pm = loss_weights(PMnetLossWeights(), weights)
        return pmnet_training_step(model, disc, batch, optimizers, w_pm)
    if isinstance(model, TDCN) and isinstance(disc, PatchDiscriminator):
        w_tdcn = loss_weights(TDCNLossWeights(), weights)
        return tdcn_training_step(model, disc, batch, optimizers, w_tdcn, fps=fps)
    if isinstance(model, SAN) and isinstance(disc, PatchDiscriminator):
        w_san = loss_weights(SANLossWeights(), weights)
        return san_training_step(model, disc, batch, optimizers, w_san, fps=fps)
    raise ValueError(
        f"no training step for model {type(model).__name__} with discriminator "
        f"{type(disc).__name__}; trainable pairs: NKN + NKNDiscriminator, PMnet + "
        "PMnetDiscriminator, TDCN or SAN + PatchDiscriminator, residual without one (copy "
        "baselines have nothing to train)"
    )
