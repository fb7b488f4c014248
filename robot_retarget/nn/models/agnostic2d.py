"""The character-agnostic 2D model (Aberman et al. 2019, adapted): 2D keypoints → the canonical
3D rotations the optimizer consumes.

The paper decomposes a sequence of 2D joint positions with three encoders — motion (dynamic,
temporal convolutions), skeleton and view (static: global pooling over time) — and decodes their
concatenation. Its decoder reconstructs 2D; ours is a head that outputs, per frame, the 22
canonical local rotations (6D, Zhou et al. 2019), the root's in the camera's heading frame
(robot_retarget.keypoints.virtual_camera): 3D ground truth exists for every training window
(CMU clips through random virtual cameras), so the head is supervised directly, and the
paper's triplet loss on the motion code (two views and skeletons of one window closer than two
windows) keeps the motion code view- and skeleton-invariant.

Adaptations for a live robot:

- The motion encoder's convolutions are causal and dilated with stride 1 (the paper's stride 2
  + upsampling needs future frames): one output per input frame, receptive field
  1 + (k − 1)·Σ dilations frames (61 at 30 fps with the defaults: 2 s).
- The static encoders pool over time causally (the mean of the frames so far) for ``stream``,
  or over the whole clip for ``convert`` (``causal=False``): the one difference between the two
  variants, both trained (each batch draws one). Their per-frame layers are 1 × 1 convolutions.
- ``centered=True`` makes a model for ``convert`` only: each motion convolution is centred on
  its frame ((k − 1)·d/2 frames before and after it), so a frame's code also sees the second
  after it, and the static encoders always pool over the whole clip. Such a model cannot run
  frame by frame (``causal=True`` is refused).
- Input: :mod:`robot_retarget.keypoints.normalize` features (x, y, visible per COCO-17 point):
  missing points are masked, the network learned them from dropouts.

The numpy twin that ``convert`` and ``stream`` run is :mod:`robot_retarget.runtime.agnostic2d`.
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.keypoints.normalize import FEATURES_PER_FRAME
from robot_retarget.runtime.agnostic2d import Agnostic2DWeights
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

Tensor = torch.Tensor
_J = len(CANONICAL_JOINTS)
LEAKY_SLOPE = 0.2  # the paper's LReLU slope


class _StaticEncoder(nn.Module):
    """Per-frame 1 × 1 convolutions, pooled over time, then a small code (skeleton or view)."""

    def __init__(self, hidden: int, code: int) -> None:
        super().__init__()
        self.layer1 = nn.Conv1d(FEATURES_PER_FRAME, hidden, 1)
        self.layer2 = nn.Conv1d(hidden, hidden, 1)
        self.code = nn.Conv1d(hidden, code, 1)

    def forward(self, x: Tensor, causal: bool) -> Tensor:
        h = nnf.leaky_relu(self.layer1(x), LEAKY_SLOPE)
        h = nnf.leaky_relu(self.layer2(h), LEAKY_SLOPE)
        if causal:
            count = torch.arange(1, h.shape[-1] + 1, device=h.device, dtype=h.dtype)
            pooled = torch.cumsum(h, dim=-1) / count
        else:
            pooled = h.mean(dim=-1, keepdim=True).expand_as(h)
        result: Tensor = self.code(pooled)
        return result


class Agnostic2D(nn.Module):
    """Motion, skeleton and view encoders and a rotation head (see the module docstring)."""

    name: ClassVar[str] = "agnostic2d"

    def __init__(
        self,
        channels: int = 96,
        kernel: int = 5,
        dilations: tuple[int, ...] = (1, 2, 4, 8),
        static_hidden: int = 64,
        skeleton_code: int = 16,
        view_code: int = 8,
        head_hidden: int = 128,
        dropout: float = 0.1,
        centered: bool = False,
    ) -> None:
        super().__init__()
        if centered and (kernel - 1) % 2:
            raise ValueError(f"a centred motion encoder needs an odd kernel, got {kernel}")
        self.channels = channels
        self.kernel = kernel
        self.dilations = tuple(int(d) for d in dilations)
        self.static_hidden = static_hidden
        self.skeleton_code = skeleton_code
        self.view_code = view_code
        self.head_hidden = head_hidden
        self.dropout = dropout
        self.centered = bool(centered)
        ins = [FEATURES_PER_FRAME] + [channels] * (len(self.dilations) - 1)
        self.motion = nn.ModuleList(
            nn.Conv1d(c, channels, kernel, dilation=d)
            for c, d in zip(ins, self.dilations, strict=True)
        )
        self.skeleton = _StaticEncoder(static_hidden, skeleton_code)
        self.view = _StaticEncoder(static_hidden, view_code)
        self.head1 = nn.Conv1d(channels + skeleton_code + view_code, head_hidden, 1)
        self.head2 = nn.Conv1d(head_hidden, _J * 6, 1)

    def config(self) -> dict[str, Any]:
        return {
            "channels": self.channels,
            "kernel": self.kernel,
            "dilations": list(self.dilations),
            "static_hidden": self.static_hidden,
            "skeleton_code": self.skeleton_code,
            "view_code": self.view_code,
            "head_hidden": self.head_hidden,
            "dropout": self.dropout,
            "centered": self.centered,
        }

    @property
    def receptive_field(self) -> int:
        return 1 + (self.kernel - 1) * sum(self.dilations)

    def encode_motion(self, features: Tensor) -> Tensor:
        """(B, T, 51) → motion code (B, C, T): causal, or centred on each frame."""
        h = features.transpose(1, 2)
        for conv, d in zip(self.motion, self.dilations, strict=True):
            span = (self.kernel - 1) * d
            pad = (span // 2, span // 2) if self.centered else (span, 0)
            h = nnf.leaky_relu(conv(nnf.pad(h, pad)), LEAKY_SLOPE)
        return h

    def forward(self, features: Tensor, causal: bool = True) -> tuple[Tensor, Tensor]:
        """Features (B, T, 51) → 6D rotations (B, T, 22, 6) and the motion code (B, C, T)."""
        if causal and self.centered:
            raise ValueError("a centred model looks ahead: run it with causal=False (convert)")
        motion = self.encode_motion(features)
        x = features.transpose(1, 2)
        z = torch.cat([motion, self.skeleton(x, causal), self.view(x, causal)], dim=1)
        h = nnf.leaky_relu(self.head1(z), LEAKY_SLOPE)
        h = nnf.dropout(h, self.dropout, self.training)
        out = self.head2(h).transpose(1, 2)
        return out.reshape(*out.shape[:2], _J, 6), motion

    def export_weights(self) -> Agnostic2DWeights:
        """The weights as numpy arrays for the runtime (float64 copies)."""

        def conv(layer: nn.Conv1d) -> tuple[Any, Any]:
            assert layer.bias is not None
            return (
                layer.weight.detach().cpu().double().numpy().copy(),
                layer.bias.detach().cpu().double().numpy().copy(),
            )

        return Agnostic2DWeights(
            dilations=tuple(float(d) for d in self.dilations),
            centered=self.centered,
            motion=tuple(conv(c) for c in self.motion),  # type: ignore[arg-type]
            skeleton=(
                conv(self.skeleton.layer1),
                conv(self.skeleton.layer2),
                conv(self.skeleton.code),
            ),
            view=(conv(self.view.layer1), conv(self.view.layer2), conv(self.view.code)),
            head=(conv(self.head1), conv(self.head2)),
        )


def rotation_6d_to_matrix(d6: Tensor) -> Tensor:
    """(…, 6) → rotation matrices (…, 3, 3) by Gram–Schmidt (Zhou et al. 2019); columns b1 b2 b3."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = nnf.normalize(a1, dim=-1)
    b2 = nnf.normalize(a2 - (b1 * a2).sum(-1, keepdim=True) * b1, dim=-1)
    b3 = torch.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)
