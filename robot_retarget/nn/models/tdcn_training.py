"""One optimisation step of TDCN with the paper's objective (Kim et al. 2020, eq. 6):

    L_c + λ_t L_t + λ_h L_h + λ_a L_a + λ_r L_r + λ_o L_o,
    λ_t = 10, λ_h = 10, λ_a = 1, λ_r = 0.1, λ_o = 1 (section 5), λ_g = 5 inside L_h.

- L_c, cycle (eq. 7): A → B → A against A, on x = [p, q, r]: the local pose and the root
  movement per frame in centimetres (the units of the paper's Mixamo data, which its weights
  were tuned in; in metres the cycle term would be 10⁴ times weaker against the others), the
  rotations as 1 − ⟨q̂, q⟩² (sign-free) and the turning rate as the arc it sweeps at 1 m
  (cm per frame: a heading drift turns the whole motion away from the source).
- L_t, twist (eq. 8): angles beyond α = 100° on both passes (robot_retarget.nn.losses).
- L_h, height (eq. 17): smooth-L1 between the height-normalised per-joint displacements of A
  and B, plus λ_g × the same on the root's distance from its start (the paper's ‖r_t‖ with
  the origin at the window's first frame, as our windows are anywhere in the room).
- L_a (eq. 21): least squares against the patch discriminator when B ≠ A, ‖x_A − x̂_B‖² when
  the target is the source's own skeleton (half the batches' samples, as the dataset draws).
- L_r (eq. 22): (1 − ‖q̂‖)² on the raw rotation outputs of both passes.
- L_o (eq. 23): smooth-L1 between the rotation angles of A's and B's heading-free root.

Optional (ours, off by default: the paper's objective alone): the project's eval metrics as
losses (robot_retarget.nn.retarget_losses: ``effector``, ``contact``, ``bone``, ``skate``) and
``denoise``: a corrupted copy of the source (robot_retarget.nn.corruption) goes through the
model and its root-relative pose and root path (from its start) are pulled onto the clean
pass's (detached), as the residual model's root-noise term.
With the paper's objective alone nothing rewards leaving copy-scaled: the cycle is met by any
invertible map, the height loss by scaling, and the adversarial term by real motion.

The discriminator learns real motion from the sources themselves (its inputs are normalised by
height, so any performer's motion is real motion for any skeleton; robots have no recorded
motion), least squares, on the samples whose target differs from the source. Adam (lr 1e-4);
generator gradients clipped to norm 25 (ours, as the other models).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import torch
from torch.nn import functional as nnf

from robot_retarget.nn.corruption import CorruptionRanges, corrupt_batch
from robot_retarget.nn.features import (
    MotionFeatures,
    compute_features,
    integrate_root,
    skeleton_height,
)
from robot_retarget.nn.losses import TWIST_ALPHA_RAD, masked_mean, twist_loss
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.nn.models.optimizers import update_generator
from robot_retarget.nn.models.tdcn import TDCN
from robot_retarget.nn.patch_discriminator import (
    PatchDiscriminator,
    patch_discriminator_step,
    patch_inputs,
)
from robot_retarget.nn.retarget_losses import (
    bone_direction_loss,
    contact_loss,
    denoising_loss,
    effector_loss,
    foot_contacts,
    foot_skate_loss,
    global_positions,
)

if TYPE_CHECKING:
    from robot_retarget.nn.models.base import RetargetModel, RetargetOutput
    from robot_retarget.nn.models.optimizers import Optimizers

Tensor = torch.Tensor


@dataclass(frozen=True)
class TDCNLossWeights:
    """The paper's weights (section 5)."""

    twist: float = 10.0
    height: float = 10.0
    height_root: float = 5.0
    adversarial: float = 1.0
    regularization: float = 0.1
    orientation: float = 1.0
    twist_alpha_rad: float = TWIST_ALPHA_RAD
    grad_clip_norm: float = 25.0
    effector: float = 0.0
    contact: float = 0.0
    bone: float = 0.0
    skate: float = 0.0
    denoise: float = 0.0


CM_PER_M = 100.0


def motion_error(a: MotionFeatures, b: MotionFeatures) -> Tensor:
    """‖x_a − x_b‖² per sample (B,), x = [p (cm), q, v (cm per frame; the turning rate as
    its arc at 1 m)]: summed over features, averaged over frames."""
    pose = (((a.local_pos - b.local_pos) * CM_PER_M) ** 2).sum((-1, -2))
    dot = (a.local_quats * b.local_quats).sum(-1)
    quats = (1.0 - dot**2).sum(-1)
    move = (((a.root_vel[..., :3] - b.root_vel[..., :3]) * CM_PER_M) ** 2).sum(-1)
    turn = ((a.root_vel[..., 3] - b.root_vel[..., 3]) * CM_PER_M) ** 2
    return (pose + quats + move + turn).mean(-1)


def _root_distance(f: MotionFeatures, height: Tensor) -> Tensor:
    """‖r_t − r_0‖ / H (B, T): the root's distance from the window's start."""
    b = f.root_vel.shape[0]
    root, _ = integrate_root(f.root_vel, f.root_vel.new_zeros(b, 3), f.root_vel.new_zeros(b))
    return torch.linalg.vector_norm(root, dim=-1) / height[:, None]


def height_loss(
    a: MotionFeatures, h_a: Tensor, b: MotionFeatures, h_b: Tensor, root_weight: float
) -> Tensor:
    """L_h (eq. 17) per sample (B,): joints summed, frames averaged."""
    step_a = torch.linalg.vector_norm(a.local_pos[:, 1:] - a.local_pos[:, :-1], dim=-1)
    step_b = torch.linalg.vector_norm(b.local_pos[:, 1:] - b.local_pos[:, :-1], dim=-1)
    joints = nnf.smooth_l1_loss(
        step_a / h_a[:, None, None], step_b / h_b[:, None, None], reduction="none"
    )
    root = nnf.smooth_l1_loss(_root_distance(a, h_a), _root_distance(b, h_b), reduction="none")
    return joints.sum(-1).mean(-1) + root_weight * root[:, 1:].mean(-1)


def rotation_angle(q: Tensor) -> Tensor:
    """E(q): rotation angle (rad, [0, π]) of quaternions (…, 4)."""
    return 2.0 * torch.atan2(torch.linalg.vector_norm(q[..., 1:], dim=-1), q[..., 0].abs())


class MetricWeights(Protocol):
    """The optional eval-metric terms' weights (0: off), as TDCN's and SAN's weights hold."""

    @property
    def effector(self) -> float: ...
    @property
    def contact(self) -> float: ...
    @property
    def bone(self) -> float: ...
    @property
    def skate(self) -> float: ...
    @property
    def denoise(self) -> float: ...


def metric_losses(
    model: RetargetModel,
    batch: RetargetBatch,
    src: MotionFeatures,
    out_b: RetargetOutput,
    w: MetricWeights,
    fps: float,
) -> dict[str, Tensor]:
    """The optional terms (see the module docstring), weighted, per sample (B,); only those
    with a weight above zero."""
    src_off, tgt_off = batch.src_offsets, batch.tgt_offsets
    pos_b = out_b.features.local_pos
    terms: dict[str, Tensor] = {}
    if w.effector > 0.0:
        terms["effector"] = w.effector * effector_loss(src.local_pos, src_off, pos_b, tgt_off)
    if w.contact > 0.0:
        terms["contact"] = w.contact * contact_loss(src.local_pos, src_off, pos_b, tgt_off)
    if w.bone > 0.0:
        terms["bone"] = w.bone * bone_direction_loss(src.local_pos, src_off, pos_b, tgt_off)
    world_b = global_positions(pos_b, out_b.root_pos, out_b.features.yaw)
    if w.skate > 0.0:
        world_src = global_positions(src.local_pos, batch.src_root_pos, src.yaw)
        planted = foot_contacts(world_src, fps, src_off)
        terms["skate"] = w.skate * foot_skate_loss(world_b, planted, fps, tgt_off)
    if w.denoise > 0.0:
        noisy_q, noisy_root = corrupt_batch(
            batch.src_local_quats, batch.src_root_pos, skeleton_height(src_off), CorruptionRanges()
        )
        noisy = compute_features(noisy_q, noisy_root, src_off)
        out_n = model.retarget_features(noisy, noisy_root[:, 0], src_off, tgt_off)
        # Root-relative poses, and root paths each from its own start: world positions would
        # compare two integrated paths, whose noise-driven drift grows without bound (on
        # world positions this term reached 10⁸ within 500 steps and the pose collapsed).
        pose = denoising_loss(out_n.features.local_pos, pos_b.detach(), tgt_off)
        path_n = out_n.root_pos - out_n.root_pos[:, :1]
        path_b = (out_b.root_pos - out_b.root_pos[:, :1]).detach()
        h = skeleton_height(tgt_off)[:, None, None]
        path = (((path_n - path_b) / h) ** 2).sum(-1).mean(-1) * 1e3
        terms["denoise"] = w.denoise * (pose + path)
    return terms


def tdcn_training_step(
    model: TDCN,
    disc: PatchDiscriminator,
    batch: RetargetBatch,
    optimizers: Optimizers,
    weights: TDCNLossWeights | None = None,
    fps: float = 30.0,
) -> dict[str, float]:
    """One generator step and one discriminator step; returns the loss terms."""
    w = weights or TDCNLossWeights()
    model.train()
    disc.train()
    src_off, tgt_off = batch.src_offsets, batch.tgt_offsets
    h_a, h_b = skeleton_height(src_off), skeleton_height(tgt_off)
    src = compute_features(batch.src_local_quats, batch.src_root_pos, src_off)
    init = batch.src_root_pos[:, 0]
    out_b = model.retarget_features(src, init, src_off, tgt_off)
    out_a = model.retarget_features(out_b.features, init, tgt_off, src_off)
    fb, fa = out_b.features, out_a.features

    same = batch.same_skeleton.to(torch.bool)
    cycle = motion_error(fa, src)
    twist = w.twist * (
        twist_loss(fb.local_quats, tgt_off, w.twist_alpha_rad)
        + twist_loss(fa.local_quats, src_off, w.twist_alpha_rad)
    )
    height = w.height * height_loss(src, h_a, fb, h_b, w.height_root)
    scores = disc(patch_inputs(fb.local_pos, fb.root_vel, tgt_off))
    lsgan = ((scores - 1.0) ** 2).mean(-1)
    square = motion_error(fb, src)
    adversarial = w.adversarial * torch.where(same, square, lsgan)
    reg = w.regularization * sum(
        ((1.0 - out.extras["quat_norm"]) ** 2).sum(-1).mean(-1) for out in (out_a, out_b)
    )
    orient = w.orientation * nnf.smooth_l1_loss(
        rotation_angle(fb.local_quats[..., 0, :]),
        rotation_angle(src.local_quats[..., 0, :]),
        reduction="none",
    ).mean(-1)
    extra = metric_losses(model, batch, src, out_b, w, fps)
    total = (cycle + twist + height + adversarial + reg + orient + sum(extra.values())).mean()
    update_generator(optimizers, model, total, w.grad_clip_norm)

    losses = {
        "total": float(total.detach()),
        "cycle": float(cycle.detach().mean()),
        "twist": float(twist.detach().mean()),
        "height": float(height.detach().mean()),
        "square": masked_mean(square, same),
        "adversarial": masked_mean(lsgan, ~same),
        "regularization": float(torch.as_tensor(reg).detach().mean()),
        "orientation": float(orient.detach().mean()),
        **{name: float(term.detach().mean()) for name, term in extra.items()},
    }
    other = ~same
    d_opt = optimizers.discriminator
    if d_opt is not None and bool(other.any()):
        losses.update(patch_discriminator_step(disc, d_opt, src, src_off, fb, tgt_off, other))
    return losses
