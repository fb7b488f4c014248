"""The seed papers' motion discriminators: 1D fully convolutional networks over time.

Both output *logits* (B,): the probability "real" is ``sigmoid(logit)``; losses use the
log-sigmoid forms, which are the papers' log D and log(1 − D) without overflow.

- :class:`NKNDiscriminator` (NKN appendix E): input = local-pose deltas p_{t+1} − p_t, root
  velocities v_t and the skeleton s̄ (tiled over time), channels first. Five conv layers of
  kernel 4; layers 1–4 stride 2 with "same" padding, leaky ReLU 0.2 and dropout (keep 0.7);
  instance normalisation on layers 2–4; layer 5 a "valid" linear conv. The paper does not give
  the channel widths; we use 64, 128, 256, 512 (constructor argument).
- :class:`PMnetDiscriminator` (PMnet Table 1): input = the scale-normalised mean-point
  trajectory (3 channels); kernel 4 stride 2 convs with 16, 32, 64, 128 channels and leaky ReLU
  0.2, then a conv to 1 channel; dropout keep 0.8.

For windows longer than the papers' 60 frames the last layer gives several positions; their
logits are averaged.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.nn.features import ROOT_VEL_DIM, MotionFeatures

Tensor = torch.Tensor

_KERNEL = 4
_STRIDE = 2


def same_pad(x: Tensor, kernel: int, stride: int) -> Tensor:
    """Pad (B, C, L) like TensorFlow's "same": length ceil(L / stride), extra padding right."""
    length = x.shape[-1]
    out = -(-length // stride)
    total = max((out - 1) * stride + kernel - length, 0)
    return nnf.pad(x, (total // 2, total - total // 2))


class ConvDiscriminator(nn.Module):
    """Strided 1D conv stack → one logit per sequence (see the module docstring)."""

    def __init__(
        self,
        in_channels: int,
        channels: Sequence[int],
        dropout: float,
        instance_norm_layers: Sequence[int] = (),
    ) -> None:
        super().__init__()
        self.in_channels = in_channels
        self.channels = tuple(channels)
        self.convs = nn.ModuleList()
        self.norms = nn.ModuleList()
        width = in_channels
        for i, c in enumerate(self.channels):
            self.convs.append(nn.Conv1d(width, c, _KERNEL, stride=_STRIDE))
            norm: nn.Module = (
                nn.InstanceNorm1d(c, affine=True) if i in instance_norm_layers else nn.Identity()
            )
            self.norms.append(norm)
            width = c
        self.out = nn.Conv1d(width, 1, _KERNEL, stride=_STRIDE)
        self.dropout = nn.Dropout(dropout)

    def forward(self, x: Tensor) -> Tensor:
        """Logits (B,) for sequences (B, C, L)."""
        for conv, norm in zip(self.convs, self.norms, strict=True):
            x = conv(same_pad(x, _KERNEL, _STRIDE))
            # Instance norm over a single time step would erase the signal: skip it then.
            if x.shape[-1] > 1:
                x = norm(x)
            x = self.dropout(nnf.leaky_relu(x, 0.2))
        if x.shape[-1] < _KERNEL:
            # Short windows: pad so the final "valid" conv still sees a full kernel.
            x = nnf.pad(x, (0, _KERNEL - x.shape[-1]))
        logits: Tensor = self.out(x)
        return logits.mean(dim=(1, 2))


class NKNDiscriminator(ConvDiscriminator):
    """NKN's skeleton-conditioned discriminator on motion deltas."""

    def __init__(
        self,
        num_joints: int = 22,
        channels: Sequence[int] = (64, 128, 256, 512),
        dropout: float = 0.3,
    ) -> None:
        self.num_joints = num_joints
        super().__init__(
            in_channels=6 * num_joints + ROOT_VEL_DIM,
            channels=channels,
            dropout=dropout,
            instance_norm_layers=(1, 2, 3),
        )

    @staticmethod
    def inputs(features: MotionFeatures, offsets: Tensor) -> Tensor:
        """(B, 6J + 4, T − 1): [p_{t+1} − p_t, v_t, s̄] for t = 1 … T − 1 (paper eq. 11)."""
        pose = features.pose_flat
        delta = pose[:, 1:] - pose[:, :-1]
        vel = features.root_vel[:, :-1]
        skel = offsets.flatten(-2)[:, None].expand(-1, delta.shape[1], -1)
        return torch.cat([delta, vel, skel], dim=-1).transpose(1, 2)


class PMnetDiscriminator(ConvDiscriminator):
    """PMnet's discriminator on the scale-normalised mean-point trajectory (B, T, 3)."""

    def __init__(self, channels: Sequence[int] = (16, 32, 64, 128), dropout: float = 0.2) -> None:
        super().__init__(in_channels=3, channels=channels, dropout=dropout)

    def forward(self, x: Tensor) -> Tensor:
        """Logits (B,) for trajectories (B, T, 3)."""
        return super().forward(x.transpose(1, 2))
