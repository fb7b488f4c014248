"""Live-sender corruption for denoising training: the torch twin of the spatial kinds of
:mod:`robot_retarget.evaluation.live_corruption`, as the live path sees them.

A position sender (a pose estimator, a marker tracker) reaches the network through the live
path's positions → rotations solve. What the denoiser has to undo is therefore not SAN's
rotation noise (:mod:`robot_retarget.nn.corruption`) but joint positions that jitter (most at
the wrists and ankles), joints frozen where they were last seen, left and right limbs swapped
for a few frames, and bones whose length changes from frame to frame, each turned into
rotations by that solve (which also drops every bone's twist and leaves the leaves at the
identity). This module applies them to a batch's world joint positions and solves them back
(:func:`robot_retarget.nn.positions_to_rotations.positions_to_rotations`).

Severities follow the evaluation's (σ = 1 % of the height, ×2.5 at the distal joints, ×1.5 at
elbows and knees; 6 frozen joints; 5 % bone-length noise), drawn per sample from ranges; the
evaluation's interval lengths are in frames of a 120 fps sender, scaled here to the training
rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from robot_retarget.evaluation import live_corruption as live
from robot_retarget.nn.fk_torch import forward_kinematics
from robot_retarget.nn.positions_to_rotations import positions_to_rotations
from robot_retarget.skeleton.canonical import ARM_CHAINS, CANONICAL_PARENTS, LEG_CHAINS, Joint

Tensor = torch.Tensor

_SENDER_FPS = 120.0  # the evaluation's intervals are counted at the CMU clips' rate
_FROZEN_JOINTS = 6


@dataclass(frozen=True)
class LiveNoise:
    """Per-sample levels: jitter σ scaled by a factor uniform in ``jitter``; frozen joints,
    swapped limbs and bone-length noise each with their probability."""

    jitter: tuple[float, float] = (0.0, 1.5)
    p_freeze: float = 0.5
    p_swap: float = 0.3
    p_bone_length: float = 0.3


def _interval(
    frames: int, lengths: tuple[int, int], fps: float, generator: torch.Generator | None
) -> tuple[int, int]:
    """[start, stop) of one interval of the evaluation's lengths at ``fps``."""
    scale = fps / _SENDER_FPS
    lo = max(1, round(lengths[0] * scale))
    hi = max(lo, round(lengths[1] * scale))
    n = int(torch.randint(lo, hi + 1, (1,), generator=generator))
    n = min(n, frames)
    start = int(torch.randint(0, frames - n + 1, (1,), generator=generator))
    return start, start + n


def corrupt_live(
    local_quats: Tensor,
    root_pos: Tensor,
    offsets: Tensor,
    heights: Tensor,
    noise: LiveNoise,
    fps: float,
    generator: torch.Generator | None = None,
) -> tuple[Tensor, Tensor]:
    """Rotations (B, T, J, 4) and root positions (B, T, 3) as a live position sender of the
    clean ``local_quats`` / ``root_pos`` on skeletons ``offsets`` (B, J, 3) of ``heights`` (B,)
    metres would deliver them, after the live path's solve."""
    b, t = local_quats.shape[:2]
    pos, _ = forward_kinematics(CANONICAL_PARENTS, offsets, local_quats, root_pos)
    pos = pos.clone()

    def uniform(lo: float, hi: float, *shape: int) -> Tensor:
        u = torch.rand(shape, generator=generator, dtype=pos.dtype).to(pos.device)
        return lo + (hi - lo) * u

    def normal(*shape: int) -> Tensor:
        return torch.randn(shape, generator=generator, dtype=pos.dtype).to(pos.device)

    def chance(p: float) -> Tensor:
        return uniform(0.0, 1.0, b) < p

    scale = uniform(*noise.jitter, b) * live.JITTER_SIGMA_FRAC * heights
    gains = torch.as_tensor(live.jitter_gains(), dtype=pos.dtype, device=pos.device)
    sigma = scale[:, None, None, None] * gains[None, None, :, None]
    pos = pos + normal(*pos.shape) * sigma
    bones = chance(noise.p_bone_length)
    if bool(bones.any()):
        f = 1.0 + normal(b, t, pos.shape[2]) * live.BONE_SIGMA * bones[:, None, None]
        out = pos.clone()
        for j, parent in enumerate(CANONICAL_PARENTS):
            if parent >= 0:
                out[:, :, j] = (
                    out[:, :, parent] + (pos[:, :, j] - pos[:, :, parent]) * f[:, :, j, None]
                )
        pos = out
    for i in torch.nonzero(chance(noise.p_freeze)).flatten().tolist():
        joints = torch.randperm(len(CANONICAL_PARENTS) - 1, generator=generator)[:_FROZEN_JOINTS]
        for j in (joints + 1).tolist():
            start, stop = _interval(t, live.DROPOUT_FRAMES, fps, generator)
            pos[i, start:stop, j] = pos[i, max(start - 1, 0), j].clone()
    for i in torch.nonzero(chance(noise.p_swap)).flatten().tolist():
        limbs = ARM_CHAINS if bool(torch.rand(1, generator=generator) < 0.5) else LEG_CHAINS
        start, stop = _interval(t, live.SWAP_FRAMES, fps, generator)
        left, right = list(limbs[0]), list(limbs[1])
        pos[i, start:stop, left + right] = pos[i, start:stop, right + left]
    return positions_to_rotations(pos, offsets), pos[..., Joint.Hips, :]
