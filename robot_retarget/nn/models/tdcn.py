"""TDCN (Kim et al., CGF 2020): temporal dilated convolutions over the motion sequence.

Per frame t the input is x_t = [p_t, q_t, v_t, s̄_B]: the source's heading-free local pose
(3J), its heading-free local rotations (4J, sign w ≥ 0), its root movement (4) and the
target's rest offsets (3J), each standardised. The network (paper Fig. 2b):

    conv k3 d1 → C                                  BN, leaky ReLU, dropout
    3 × residual block: conv k3 d3^i → C, conv 1×1 → C   (each BN, leaky ReLU, dropout)
    conv 1×1 → C, leaky ReLU                        (high-level features)
    conv 1×1 → 4J + 4                               (rotations and root movement)

Receptive field with k = 3: 1 + 2·(1 + 3 + 9 + 27) = 81 frames, as published. Sequences are
padded with their first frame on the left and their last on the right (the paper pads the
input with x_1 and x_T); here every layer pads its own input that way, so a clip of any length
gives one output per frame. ``causal=True`` pads on the left only (the paper's ablation A5):
frame t then sees frames t − 80 … t, and :meth:`TDCN.step` keeps, per layer, a ring of the
last (k − 1)·d inputs, started with copies of the first frame as the left padding is, so the
step equals the clip path frame for frame at O(layers) per frame.

Deviations (ours, stated):

- C = 256 channels by default instead of 1024, so the causal numpy step
  (robot_retarget.runtime.tdcn) fits the live path's 0.3 ms budget; ``channels=1024`` builds
  the published width.
- The rotation head predicts a correction Δq, q_B = q_A ⊗ Δq / ‖Δq‖, started at the
  identity, instead of the rotations themselves (``residual_rotations=False`` for the
  paper's direct regression). Learned from scratch, the papers' direct outputs scored 19–27°
  of bone direction here (NKN, PMnet) against copy's 5.7°.
- Our models integrate the root from velocities (robot_retarget.nn.models.base) rather than
  output the root position: the root head predicts the height-normalised movement
  v_B / H_B = v_A / H_A + Δv and the turning rate ω_B = ω_A + Δω, both started at zero, so an
  untrained TDCN is copy-scaled.

Losses (robot_retarget.nn.models.tdcn_training) are the paper's: cycle, twist, height,
least-squares adversarial against a patch discriminator of receptive field 31
(robot_retarget.nn.patch_discriminator), quaternion-norm regularisation and orientation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import (
    ROOT_VEL_DIM,
    FrameFeatures,
    MotionFeatures,
    skeleton_height,
)
from robot_retarget.nn.models.base import Prediction, RetargetModel
from robot_retarget.nn.models.normalization import Standardizer
from robot_retarget.nn.models.weight_export import layer_pair, to_numpy
from robot_retarget.nn.temporal_padding import pad_time

if TYPE_CHECKING:
    from robot_retarget.runtime.model import RuntimeModel
    from robot_retarget.runtime.tdcn import TDCNWeights

Tensor = torch.Tensor

_SLOPE = 0.2
# The rotation head starts within ~1e-2 of the identity correction (as NKN's and PMnet's).
_QUAT_INIT_SCALE = 1e-2


def receptive_field(kernel_size: int, dilations: tuple[int, ...]) -> int:
    """Frames one output sees: 1 + (k − 1)·Σ d over the temporal convolutions."""
    return 1 + (kernel_size - 1) * sum(dilations)


class TemporalLayer(nn.Module):
    """Conv1d (no bias) → batch norm → leaky ReLU → dropout, padded to keep the length."""

    def __init__(
        self, in_ch: int, out_ch: int, kernel: int, dilation: int, dropout: float, causal: bool
    ) -> None:
        super().__init__()
        self.conv = nn.Conv1d(in_ch, out_ch, kernel, dilation=dilation, bias=False)
        self.norm = nn.BatchNorm1d(out_ch)
        self.dropout = nn.Dropout(dropout)
        self.causal = causal
        self.span = (kernel - 1) * dilation
        self._history: Tensor | None = None

    def _post(self, x: Tensor) -> Tensor:
        return self.dropout(nnf.leaky_relu(self.norm(x), _SLOPE))

    def forward(self, x: Tensor) -> Tensor:
        """(B, C_in, T) → (B, C_out, T)."""
        s = self.span
        padded = pad_time(x, s, 0) if self.causal else pad_time(x, s // 2, s - s // 2)
        return self._post(self.conv(padded))

    def reset(self) -> None:
        self._history = None

    def step(self, x: Tensor) -> Tensor:
        """One frame (B, C_in) → (B, C_out), equal to :meth:`forward`'s frame on the clip."""
        col = x[:, :, None]
        if self._history is None:
            self._history = col.expand(-1, -1, self.span)  # the left padding
        window = torch.cat([self._history, col], dim=-1)
        self._history = window[:, :, 1:]
        return self._post(self.conv(window))[:, :, 0]


class TDCN(RetargetModel):
    """Temporal dilated convolutional network retargeter (see the module docstring)."""

    name = "tdcn"

    def __init__(
        self,
        channels: int = 256,
        blocks: int = 3,
        kernel_size: int = 3,
        dropout: float = 0.1,
        causal: bool = True,
        residual_rotations: bool = True,
    ) -> None:
        super().__init__()
        if kernel_size < 2 or blocks < 0 or channels < 1:
            raise ValueError(
                f"need kernel_size ≥ 2, blocks ≥ 0, channels ≥ 1; got {kernel_size}, "
                f"{blocks}, {channels}"
            )
        self.channels = channels
        self.blocks = blocks
        self.kernel_size = kernel_size
        self.dropout = dropout
        self.causal = causal
        self.residual_rotations = residual_rotations
        j = self.num_joints
        self.pose_norm = Standardizer(3 * j)
        self.quat_norm = Standardizer(4 * j)
        self.vel_norm = Standardizer(ROOT_VEL_DIM)
        self.offset_norm = Standardizer(3 * j)
        in_dim = 3 * j + 4 * j + ROOT_VEL_DIM + 3 * j
        self.dilations = tuple(kernel_size**i for i in range(blocks + 1))
        self.expand = TemporalLayer(in_dim, channels, kernel_size, 1, dropout, causal)
        self.dilated = nn.ModuleList(
            TemporalLayer(channels, channels, kernel_size, d, dropout, causal)
            for d in self.dilations[1:]
        )
        self.pointwise = nn.ModuleList(
            TemporalLayer(channels, channels, 1, 1, dropout, causal) for _ in self.dilations[1:]
        )
        self.features = nn.Conv1d(channels, channels, 1)
        self.head = nn.Conv1d(channels, 4 * j + ROOT_VEL_DIM, 1)
        head_bias = self.head.bias
        assert head_bias is not None
        with torch.no_grad():
            self.head.weight.mul_(_QUAT_INIT_SCALE)
            self.head.weight[4 * j :].zero_()
            head_bias.zero_()
            head_bias[: 4 * j].copy_(qt.identity((j,)).flatten())

    @property
    def receptive_field(self) -> int:
        """Frames each output sees (81 for the published 3 blocks of kernel 3)."""
        return receptive_field(self.kernel_size, self.dilations)

    def config(self) -> dict[str, Any]:
        return {
            "channels": self.channels,
            "blocks": self.blocks,
            "kernel_size": self.kernel_size,
            "dropout": self.dropout,
            "causal": self.causal,
            "residual_rotations": self.residual_rotations,
        }

    def fit_normalization(self, features: MotionFeatures, offsets: Tensor) -> None:
        self.pose_norm.fit(features.pose_flat)
        self.quat_norm.fit(qt.canonical_sign(features.local_quats).flatten(-2))
        self.vel_norm.fit(features.root_vel)
        self.offset_norm.fit(offsets.flatten(-2))

    def _inputs(self, pose: Tensor, quats: Tensor, vel: Tensor, tgt_in: Tensor) -> Tensor:
        """[p, q, v, s̄_B] standardised, (…, in_dim)."""
        return torch.cat(
            [
                self.pose_norm(pose.flatten(-2)),
                self.quat_norm(qt.canonical_sign(quats).flatten(-2)),
                self.vel_norm(vel),
                tgt_in,
            ],
            dim=-1,
        )

    def _outputs(
        self,
        raw: Tensor,
        src_quats: Tensor,
        src_vel: Tensor,
        src_offsets: Tensor,
        tgt_offsets: Tensor,
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Head output (…, 4J + 4) → rotations (…, J, 4), root velocity (…, 4), and the raw
        quaternion norms (…, J) for the regularisation loss."""
        j = self.num_joints
        raw_q = raw[..., : 4 * j].reshape(*raw.shape[:-1], j, 4)
        norms = torch.linalg.vector_norm(raw_q, dim=-1)
        unit = qt.normalize(raw_q)
        quats = qt.normalize(qt.mul(src_quats, unit)) if self.residual_rotations else unit
        extra = (1,) * (src_vel.ndim - 1)
        h_src = skeleton_height(src_offsets).view(-1, *extra)
        h_tgt = skeleton_height(tgt_offsets).view(-1, *extra)
        dv = raw[..., 4 * j :]
        move = (src_vel[..., :3] / h_src + dv[..., :3]) * h_tgt
        turn = src_vel[..., 3:] + dv[..., 3:]
        return quats, torch.cat([move, turn], dim=-1), norms

    def _trunk(self, h: Tensor, layer_step: bool) -> Tensor:
        """The convolution stack on (B, C, T) clips, or on (B, C) frames when stepping."""
        h = self.expand.step(h) if layer_step else self.expand(h)
        for dil, point in self._blocks():
            inner = dil.step(h) if layer_step else dil(h)
            h = h + (point.step(inner) if layer_step else point(inner))
        if layer_step:
            out: Tensor = self.head(nnf.leaky_relu(self.features(h[:, :, None]), _SLOPE))[:, :, 0]
            return out
        out = self.head(nnf.leaky_relu(self.features(h), _SLOPE))
        return out

    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        t = src.root_vel.shape[1]
        tgt_in = self.offset_norm(tgt_offsets.flatten(-2))[:, None].expand(-1, t, -1)
        x = self._inputs(src.local_pos, src.local_quats, src.root_vel, tgt_in)
        raw = self._trunk(x.transpose(1, 2), layer_step=False).transpose(1, 2)
        quats, vel, norms = self._outputs(
            raw, src.local_quats, src.root_vel, src_offsets, tgt_offsets
        )
        return Prediction(local_quats=quats, root_vel=vel, extras={"quat_norm": norms})

    def _blocks(self) -> list[tuple[TemporalLayer, TemporalLayer]]:
        """(dilated, pointwise) layers of each residual block."""
        return [
            (cast(TemporalLayer, d), cast(TemporalLayer, p))
            for d, p in zip(self.dilated, self.pointwise, strict=True)
        ]

    def _layers(self) -> list[TemporalLayer]:
        return [self.expand, *(layer for block in self._blocks() for layer in block)]

    def reset_state(self) -> None:
        for layer in self._layers():
            layer.reset()

    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        if not self.causal:
            # A RetargetError, so stream and convert (which step frame by frame) say what to do.
            raise ModelLoadError(
                "this TDCN is non-causal (each frame needs 40 future frames) and has no online "
                "step: score it with eval, or train one with --model-config causal=true (the "
                "shipped tdcn is causal) to stream or convert",
                model=self.name,
            )
        quats = src.local_quats
        tgt_in = self.offset_norm(tgt_offsets.flatten(-2))
        x = self._inputs(src.local_pos, quats, src.root_vel, tgt_in)
        raw = self._trunk(x, layer_step=True)
        q_b, vel, _ = self._outputs(raw, quats, src.root_vel, src_offsets, tgt_offsets)
        return q_b, vel

    def runtime(self) -> RuntimeModel | None:
        """The numpy step exists for the causal TDCN (the online path); None otherwise."""
        if not self.causal:
            return None
        from robot_retarget.runtime.model import RuntimeModel

        return RuntimeModel(name=self.name, architecture="tdcn", weights=self.export_weights())

    @torch.no_grad()
    def export_weights(self) -> TDCNWeights:
        """Parameters as numpy arrays with batch norm folded into each convolution."""
        from robot_retarget.runtime.tdcn import TDCNWeights

        def folded(layer: TemporalLayer) -> tuple[Any, Any]:
            bn = layer.norm
            mean, var = bn.running_mean, bn.running_var
            assert mean is not None
            assert var is not None
            scale = bn.weight / torch.sqrt(var + bn.eps)
            kernel = layer.conv.weight * scale[:, None, None]
            bias = bn.bias - mean * scale
            return to_numpy(kernel), to_numpy(bias)

        return TDCNWeights(
            dilations=tuple(float(d) for d in self.dilations),
            flags=(float(self.causal), float(self.residual_rotations)),
            pose_mean=to_numpy(self.pose_norm.mean),
            pose_std=to_numpy(self.pose_norm.std),
            quat_mean=to_numpy(self.quat_norm.mean),
            quat_std=to_numpy(self.quat_norm.std),
            vel_mean=to_numpy(self.vel_norm.mean),
            vel_std=to_numpy(self.vel_norm.std),
            offset_mean=to_numpy(self.offset_norm.mean),
            offset_std=to_numpy(self.offset_norm.std),
            expand=folded(self.expand),
            dilated=tuple(folded(d) for d, _ in self._blocks()),
            pointwise=tuple(folded(p) for _, p in self._blocks()),
            features=layer_pair(self.features),
            head=layer_pair(self.head),
        )
