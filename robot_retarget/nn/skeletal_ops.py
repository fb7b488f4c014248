"""Skeleton-aware convolution, pooling and unpooling (SAN, Aberman et al. 2020, section 4).

Features live on armatures: (B, A, C, T) for A armatures, C channels each, T frames.

- :class:`SkeletalConv`: armature a's output is a temporal convolution of the armatures within
  graph distance d of a (its neighbourhood, robot_retarget.skeleton.armatures); the kernels
  are *not* shared across armatures (a knee moves unlike a spine). Implemented as one dense
  Conv1d over all armatures' channels whose weight is masked to the neighbourhoods, as the
  paper's reference code does. ``causal`` pads on the left only (frame t sees t − k + 1 … t),
  with copies of the first frame, so a clip and a frame-by-frame stream agree.
- :class:`SkeletalPool`: the mean of each group of merged armatures.
- :class:`SkeletalUnpool`: each armature takes its group's features (the inverse's shape).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.nn.temporal_padding import pad_time
from robot_retarget.skeleton.armatures import PoolLevel

Tensor = torch.Tensor


def _block_mask(
    neighbours: Sequence[Sequence[int]], in_channels: Sequence[int], out_channels: Sequence[int]
) -> Tensor:
    """(Σ out, Σ in) 0/1: output block a reads the input blocks of a's neighbours."""
    starts_in = [0]
    for c in in_channels:
        starts_in.append(starts_in[-1] + c)
    mask = torch.zeros(sum(out_channels), sum(in_channels))
    row = 0
    for a, near in enumerate(neighbours):
        for b in near:
            mask[row : row + out_channels[a], starts_in[b] : starts_in[b + 1]] = 1.0
        row += out_channels[a]
    return mask


class SkeletalConv(nn.Module):
    """Skeleto-temporal convolution on one pooling level (see the module docstring).

    ``in_channels`` / ``out_channels`` are per armature (the root armature may carry more,
    e.g. its movement); kernel ``kernel_size`` frames, neighbourhood ``distance``. Only the
    weights inside the neighbourhoods are parameters (``weight``: (nnz, k)); the dense kernel
    is assembled per call.
    """

    rows: Tensor
    cols: Tensor

    def __init__(
        self,
        level: PoolLevel,
        in_channels: Sequence[int],
        out_channels: Sequence[int],
        *,
        kernel_size: int,
        distance: int = 2,
        causal: bool = True,
    ) -> None:
        super().__init__()
        if len(in_channels) != level.size or len(out_channels) != level.size:
            raise ValueError(
                f"channel lists must have one entry per armature ({level.size}), got "
                f"{len(in_channels)} and {len(out_channels)}"
            )
        if kernel_size < 1:
            raise ValueError(f"kernel_size must be at least 1, got {kernel_size}")
        self.in_channels = tuple(in_channels)
        self.out_channels = tuple(out_channels)
        self.kernel_size = kernel_size
        self.causal = causal
        mask = _block_mask(level.neighbours(distance), in_channels, out_channels)
        rows, cols = torch.nonzero(mask, as_tuple=True)
        # Derived from the topology: rebuilt, not saved.
        self.register_buffer("rows", rows, persistent=False)
        self.register_buffer("cols", cols, persistent=False)
        self.weight = nn.Parameter(torch.empty(rows.numel(), kernel_size))
        self.bias = nn.Parameter(torch.zeros(sum(out_channels)))
        # He-uniform over each output's true fan-in (its neighbourhood), not the dense width.
        fan_in = (mask.sum(1) * kernel_size).clamp_min(1.0)[rows]
        bound = torch.sqrt(3.0 / fan_in)[:, None]
        with torch.no_grad():
            self.weight.uniform_(-1.0, 1.0)
            self.weight.mul_(bound)

    def dense_weight(self) -> Tensor:
        """The kernel (Σ C_out, Σ C_in, k), zero outside the neighbourhoods."""
        w = self.weight.new_zeros(sum(self.out_channels), sum(self.in_channels), self.kernel_size)
        return w.index_put((self.rows, self.cols), self.weight)

    def _load_from_state_dict(  # type: ignore[no-untyped-def]
        self, state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
    ) -> None:
        # Checkpoints of the first SAN runs stored the dense kernel and its mask.
        state_dict.pop(prefix + "mask", None)
        dense = state_dict.get(prefix + "weight")
        if dense is not None and dense.ndim == 3:
            state_dict[prefix + "weight"] = dense[self.rows, self.cols]
        super()._load_from_state_dict(
            state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
        )

    def forward(self, x: Tensor) -> Tensor:
        """(B, A, C_in, T) with per-armature C_in as built (or (B, ΣC_in, T)) → (B, ΣC_out, T)."""
        if x.ndim == 4:
            x = x.flatten(1, 2)
        span = self.kernel_size - 1
        x = pad_time(x, span, 0) if self.causal else pad_time(x, span // 2, span - span // 2)
        return nnf.conv1d(x, self.dense_weight(), self.bias)


class SkeletalPool(nn.Module):
    """Mean over each group of armatures; input and output have ``channels`` per armature."""

    matrix: Tensor

    def __init__(self, groups: Sequence[Sequence[int]], num_in: int) -> None:
        super().__init__()
        m = torch.zeros(len(groups), num_in)
        for g, members in enumerate(groups):
            m[g, list(members)] = 1.0 / len(members)
        if not torch.all(m.sum(0) > 0):
            raise ValueError("every armature must belong to a group")
        self.register_buffer("matrix", m)

    def forward(self, x: Tensor) -> Tensor:
        """(B, A_in, C, T) → (B, A_out, C, T)."""
        return torch.einsum("ga,bact->bgct", self.matrix, x)


class SkeletalUnpool(nn.Module):
    """Each armature of the finer level takes its group's features."""

    matrix: Tensor

    def __init__(self, groups: Sequence[Sequence[int]], num_out: int) -> None:
        super().__init__()
        m = torch.zeros(num_out, len(groups))
        for g, members in enumerate(groups):
            m[list(members), g] = 1.0
        self.register_buffer("matrix", m)

    def forward(self, x: Tensor) -> Tensor:
        """(B, A_coarse, C, T) → (B, A_fine, C, T)."""
        return torch.einsum("ag,bgct->bact", self.matrix, x)
