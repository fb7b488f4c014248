"""TDCN's patch discriminator (Kim et al. 2020, section 4.1 and Fig. 3).

A temporal dilated convolutional network like the generator, but each output sees only 31
frames, so it scores local stretches of motion (PatchGAN) rather than the whole window:
kernel 3 with dilations 1, 2, 4, 8 gives 1 + 2·(1 + 2 + 4 + 8) = 31. The convolutions are
"valid" (no padding): every score is of a real 31-frame patch. Input per frame (eqs. 18–20):
each joint's displacement since the previous frame over the skeleton's height
l_t = ‖p_t − p_{t−1}‖ / H (J), the root's δ_t = ‖r_t − r_{t−1}‖ / H (1), and the bone
lengths over the height (J, tiled over time). Output: one least-squares score per patch
(B, T − 31); losses in robot_retarget.nn.models.tdcn_training.

Reused from robot_retarget.nn.discriminators: leaky ReLU 0.2 and dropout after every hidden
layer (the seed discriminators' recipe); there, strided convolutions pool a window into one
logit, which is exactly what a patch discriminator must not do, hence this separate network.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.nn.features import MotionFeatures, integrate_root, skeleton_height

Tensor = torch.Tensor

PATCH_DILATIONS: tuple[int, ...] = (1, 2, 4, 8)
"""Dilations of the discriminator's kernel-3 convolutions: a 31-frame receptive field."""


def patch_inputs(local_pos: Tensor, root_vel: Tensor, offsets: Tensor) -> Tensor:
    """(B, 2J + 1, T − 1): [l_t, δ_t, bone lengths] / height for t = 1 … T − 1 (see the
    module docstring). ``local_pos`` (B, T, J, 3), ``root_vel`` (B, T, 4), ``offsets`` (B, J, 3).
    """
    h = skeleton_height(offsets)[:, None, None]
    b = root_vel.shape[0]
    root, _ = integrate_root(root_vel, root_vel.new_zeros(b, 3), root_vel.new_zeros(b))
    joint_motion = torch.linalg.vector_norm(local_pos[:, 1:] - local_pos[:, :-1], dim=-1) / h
    root_motion = torch.linalg.vector_norm(root[:, 1:] - root[:, :-1], dim=-1)[..., None] / h
    bones = (torch.linalg.vector_norm(offsets, dim=-1)[:, None] / h).expand(
        -1, joint_motion.shape[1], -1
    )
    return torch.cat([joint_motion, root_motion, bones], dim=-1).transpose(1, 2)


class PatchDiscriminator(nn.Module):
    """Dilated 1D convolutions → one score per 31-frame patch (see the module docstring)."""

    def __init__(
        self,
        num_joints: int = 22,
        channels: int = 256,
        dilations: Sequence[int] = PATCH_DILATIONS,
        dropout: float = 0.1,
    ) -> None:
        super().__init__()
        self.num_joints = num_joints
        self.dilations = tuple(dilations)
        width = 2 * num_joints + 1
        self.convs = nn.ModuleList()
        for d in self.dilations:
            self.convs.append(nn.Conv1d(width, channels, 3, dilation=d))
            width = channels
        self.out = nn.Conv1d(width, 1, 1)
        self.dropout = nn.Dropout(dropout)

    @property
    def receptive_field(self) -> int:
        return 1 + 2 * sum(self.dilations)

    def forward(self, x: Tensor) -> Tensor:
        """Scores (B, L − receptive_field + 1) for inputs (B, 2J + 1, L)."""
        if x.shape[-1] < self.receptive_field:
            raise ValueError(
                f"the patch discriminator needs windows of at least {self.receptive_field} "
                f"motion frames, got {x.shape[-1]}; train with a longer --window"
            )
        for conv in self.convs:
            x = self.dropout(nnf.leaky_relu(conv(x), 0.2))
        scores: Tensor = self.out(x)
        return scores[:, 0]


def patch_discriminator_step(
    disc: PatchDiscriminator,
    optimizer: torch.optim.Optimizer,
    real: MotionFeatures,
    real_offsets: Tensor,
    fake: MotionFeatures,
    fake_offsets: Tensor,
    mask: Tensor,
) -> dict[str, float]:
    """One least-squares update on the ``mask``ed samples: ``real`` motion scores 1, the
    generator's ``fake`` (detached here) 0. Returns the loss and the mean fake score."""
    optimizer.zero_grad(set_to_none=True)
    real_scores = disc(patch_inputs(real.local_pos, real.root_vel, real_offsets))
    fake_scores = disc(patch_inputs(fake.local_pos.detach(), fake.root_vel.detach(), fake_offsets))
    loss = (((real_scores - 1.0) ** 2).mean(-1) + (fake_scores**2).mean(-1))[mask].mean()
    loss.backward()
    optimizer.step()
    return {
        "discriminator": float(loss.detach()),
        "disc_fake_score": float(fake_scores.detach()[mask].mean()),
    }
