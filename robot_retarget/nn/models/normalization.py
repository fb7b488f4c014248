"""Per-feature input normalisation kept inside a model (buffers, saved with its weights)."""

from __future__ import annotations

import torch
from torch import nn

Tensor = torch.Tensor

# A feature whose spread is below this (the root's own position, always zero) is not scaled.
_MIN_STD = 1e-4


class Standardizer(nn.Module):
    """``(x − mean) / std`` over the last axis, with statistics fitted from data.

    Starts as the identity (mean 0, std 1); :meth:`fit` sets the statistics from a sample
    (…, D). The buffers travel with ``state_dict``, so a checkpoint restores them. ``min_std``
    floors the fitted spreads: a feature that barely varies in training would otherwise be
    divided by its tiny spread and make the network hypersensitive to it at run time.
    """

    mean: Tensor
    std: Tensor

    def __init__(self, dim: int, min_std: float | None = None) -> None:
        super().__init__()
        self.dim = dim
        self.min_std = min_std
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("std", torch.ones(dim))

    @torch.no_grad()
    def fit(self, sample: Tensor) -> None:
        """Set mean and std from ``sample`` (…, D); near-constant features keep std 1."""
        if sample.shape[-1] != self.dim:
            raise ValueError(f"expected a last axis of {self.dim}, got {tuple(sample.shape)}")
        flat = sample.reshape(-1, self.dim).to(self.mean)
        std = flat.std(dim=0, unbiased=False) if flat.shape[0] > 1 else torch.ones_like(self.std)
        self.mean.copy_(flat.mean(dim=0))
        if self.min_std is not None:
            std = std.clamp_min(self.min_std)
        self.std.copy_(torch.where(std < _MIN_STD, torch.ones_like(std), std))

    def forward(self, x: Tensor) -> Tensor:
        return (x - self.mean) / self.std

    def inverse(self, z: Tensor) -> Tensor:
        """Map normalised values back to data units."""
        return z * self.std + self.mean
