"""Padding along time by repeating the edge frames: what keeps a convolved clip its length and
lets a causal layer stepped frame by frame (its ring started with the first frame) agree with
the clip path. Used by TDCN's temporal layers and SAN's skeletal convolutions."""

from __future__ import annotations

import torch

Tensor = torch.Tensor


def pad_time(x: Tensor, left: int, right: int) -> Tensor:
    """Pad (B, C, T) by repeating its first frame ``left`` times and its last ``right`` times."""
    if left == 0 and right == 0:
        return x
    return torch.cat([x[..., :1].expand(-1, -1, left), x, x[..., -1:].expand(-1, -1, right)], -1)
