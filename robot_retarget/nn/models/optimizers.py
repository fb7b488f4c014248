"""The optimisers a training step updates, and the generator update every step ends with."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

LEARNING_RATE = 1e-4


@dataclass(frozen=True)
class Optimizers:
    """The generator's (retargeting model's) and the discriminator's optimisers."""

    generator: torch.optim.Optimizer
    discriminator: torch.optim.Optimizer | None


def make_optimizers(
    model: nn.Module, discriminator: nn.Module | None, lr: float = LEARNING_RATE
) -> Optimizers:
    """Adam for both networks (both papers: learning rate 1e-4); a model trained without a
    discriminator gets none."""
    return Optimizers(
        generator=torch.optim.Adam(model.parameters(), lr=lr),
        discriminator=(
            None if discriminator is None else torch.optim.Adam(discriminator.parameters(), lr=lr)
        ),
    )


def update_generator(
    optimizers: Optimizers, model: nn.Module, total: torch.Tensor, grad_clip_norm: float
) -> None:
    """One generator update on ``total``: gradients, clipped to ``grad_clip_norm``, then a step."""
    optimizers.generator.zero_grad(set_to_none=True)
    total.backward()  # type: ignore[no-untyped-call]
    nn.utils.clip_grad_norm_(model.parameters(), grad_clip_norm)
    optimizers.generator.step()
