"""Random input corruption for denoising training: the torch twin of evaluation/noise.py.

Live sources (pose estimators, marker-based mocap with occlusions) deliver rotations with
jitter and dropped joints. Training a model on corrupted input against the clean motion
teaches it to filter both. The corruption follows SAN's protocol as the ``eval`` command
applies it (:func:`robot_retarget.evaluation.noise.corrupt`): Gaussian noise on the root
position (σ = ``sigma_frac`` × height), a random rotation with rotation-vector σ =
``sigma_frac`` × 6 rad on every non-root joint, and joints "zeroed" (identity) with
probability ``zero_prob``; the root orientation is left clean. Here σ and the zero probability
are drawn per sample from ranges, so the model sees every level from clean to twice the
evaluation's; ``p_clean`` leaves a share of samples untouched.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.live_noise import LiveNoise

Tensor = torch.Tensor

# Typical segment length as a fraction of height (as in evaluation/noise.py).
_SEGMENT_FRAC = 1.0 / 6.0


@dataclass(frozen=True)
class CorruptionRanges:
    """Per-sample corruption levels: σ and zero probability uniform in their ranges.

    ``p_clean`` is the share of samples left untouched, so the model also learns to pass
    clean input through unchanged.
    """

    sigma_frac: tuple[float, float] = (0.0, 0.02)
    zero_prob: tuple[float, float] = (0.0, 0.04)
    p_clean: float = 0.0
    # The share of samples corrupted as a live position sender's instead
    # (robot_retarget.nn.live_noise, applied by the residual training step), and its levels.
    live_share: float = 0.0
    live: LiveNoise = field(default_factory=LiveNoise)


def corrupt_batch(
    local_quats: Tensor,
    root_pos: Tensor,
    heights: Tensor,
    ranges: CorruptionRanges,
    generator: torch.Generator | None = None,
) -> tuple[Tensor, Tensor]:
    """Corrupted copies of rotations (B, T, J, 4) and root positions (B, T, 3).

    ``heights`` (B,) metres scale the positional noise. Draws from ``generator`` (torch's
    global generator when None), so a seeded training step corrupts reproducibly.
    """
    b = local_quats.shape[0]

    def uniform(lo: float, hi: float, *shape: int) -> Tensor:
        u = torch.rand(shape, generator=generator, dtype=local_quats.dtype)
        return (lo + (hi - lo) * u).to(local_quats.device)

    def normal(*shape: int) -> Tensor:
        n = torch.randn(shape, generator=generator, dtype=local_quats.dtype)
        return n.to(local_quats.device)

    noisy_sample = uniform(0.0, 1.0, b) >= ranges.p_clean
    sigma = uniform(*ranges.sigma_frac, b) * noisy_sample
    zero_p = uniform(*ranges.zero_prob, b) * noisy_sample
    rot_sigma = (sigma / _SEGMENT_FRAC).view(b, 1, 1, 1)
    noise = qt.from_rotation_vector(normal(*local_quats.shape[:-1], 3) * rot_sigma)
    noisy = qt.mul(local_quats, noise)
    zeroed = uniform(0.0, 1.0, *local_quats.shape[:-1]) < zero_p.view(b, 1, 1)
    noisy = torch.where(zeroed[..., None], qt.identity(noisy.shape[:-1]).to(noisy), noisy)
    noisy = torch.cat([local_quats[..., :1, :], noisy[..., 1:, :]], dim=-2)
    pos_sigma = (sigma * heights).view(b, 1, 1)
    noisy_root = root_pos + normal(*root_pos.shape) * pos_sigma
    return qt.normalize(noisy), noisy_root
