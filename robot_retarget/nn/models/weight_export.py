"""Parameters as float64 numpy arrays, for the numpy twins of the models' online steps
(robot_retarget.pipeline.fast_*), which must not depend on torch."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from robot_retarget.array_types import FloatArray


def to_numpy(t: torch.Tensor) -> FloatArray:
    """A detached float64 copy of ``t`` on the CPU."""
    return np.asarray(t.detach().cpu().double().numpy(), dtype=np.float64)


def layer_pair(layer: nn.Linear | nn.Conv1d) -> tuple[FloatArray, FloatArray]:
    """(weight, bias) of a layer that has a bias."""
    if layer.bias is None:
        raise ValueError(f"{type(layer).__name__} has no bias to export")
    return to_numpy(layer.weight), to_numpy(layer.bias)


def linear_pairs(module: nn.Module) -> tuple[tuple[FloatArray, FloatArray], ...]:
    """(weight, bias) of every Linear in ``module``, in order."""
    return tuple(layer_pair(m) for m in module.modules() if isinstance(m, nn.Linear))
