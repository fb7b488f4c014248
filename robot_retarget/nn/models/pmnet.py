"""PMnet (Lim et al., BMVC 2019): disentangled pose and movement retargeting.

Pose, per frame (eqs. 1–5, Table 1):

    φ_A = F_P(p_A)                         4 × fc 512, ReLU
    q_A = F_q(φ_A) / ‖·‖                   fc 4J (reconstructs A's pose on ref_A)
    Δq  = F_Δ([φ_A, ref_B]) / ‖·‖          fc 4J
    q_B = q_A ⊗ Δq                         (Hamilton product, per joint)

Movement (eqs. 6–7): the root velocity's x, y, z are divided by the source's scale S_A
(:func:`robot_retarget.nn.features.pmnet_scale`), F_M (1D convs: k3 → 128 leaky ReLU → k3 → 4)
regresses the target's normalised movement, and x, y, z are multiplied by S_B.

Dropout with keep probability 0.8 after every hidden layer, as in the paper's Table 1.

Deviation, for the online path: F_M's convolutions are *causal* (padded on the past side)
instead of centred, so frame t's movement depends on frames t−4…t only and :meth:`PMnet.step`
keeps per-layer buffers of the last k − 1 inputs instead of waiting for future frames. Set
``causal_movement=False`` for the paper's centred convolutions (clip path only; ``step`` then
raises). Inputs are standardised with statistics fitted from training data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.geometry.quaternion_tables import product_table
from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import (
    ROOT_VEL_DIM,
    FrameFeatures,
    MotionFeatures,
    pmnet_scale,
)
from robot_retarget.nn.models.base import Prediction, RetargetModel
from robot_retarget.nn.models.normalization import Standardizer
from robot_retarget.nn.models.weight_export import layer_pair, linear_pairs, to_numpy
from robot_retarget.runtime.pmnet import PMnetWeights

if TYPE_CHECKING:
    from robot_retarget.runtime.model import RuntimeModel

Tensor = torch.Tensor

_QUAT_INIT_SCALE = 1e-2


class MovementRegressor(nn.Module):
    """F_M: 1D convolutions over time on (B, T, 4) normalised root movement."""

    def __init__(self, channels: int, kernel_size: int, dropout: float, causal: bool) -> None:
        super().__init__()
        self.kernel_size = kernel_size
        self.causal = causal
        self.conv1 = nn.Conv1d(ROOT_VEL_DIM, channels, kernel_size)
        self.conv2 = nn.Conv1d(channels, ROOT_VEL_DIM, kernel_size)
        self.dropout = nn.Dropout(dropout)
        self._buffers_in: list[Tensor] | None = None

    def _pad(self, x: Tensor) -> Tensor:
        k = self.kernel_size - 1
        return nnf.pad(x, (k, 0) if self.causal else (k // 2, k - k // 2))

    def _hidden(self, x: Tensor) -> Tensor:
        return self.dropout(nnf.leaky_relu(x, 0.2))

    def forward(self, nv: Tensor) -> Tensor:
        x = nv.transpose(1, 2)
        x = self._hidden(self.conv1(self._pad(x)))
        return self.conv2(self._pad(x)).transpose(1, 2)

    def reset(self) -> None:
        self._buffers_in = None

    def step(self, nv: Tensor) -> Tensor:
        """One frame (B, 4) → (B, 4), equal to :meth:`forward`'s frame on the whole clip."""
        if not self.causal:
            raise RuntimeError("the centred movement regressor needs future frames: no step()")
        k = self.kernel_size - 1
        if self._buffers_in is None:
            self._buffers_in = [
                nv.new_zeros(nv.shape[0], ROOT_VEL_DIM, k),
                nv.new_zeros(nv.shape[0], self.conv1.out_channels, k),
            ]
        buf1, buf2 = self._buffers_in
        win1 = torch.cat([buf1, nv[:, :, None]], dim=-1)
        h = self._hidden(self.conv1(win1))
        win2 = torch.cat([buf2, h], dim=-1)
        out = self.conv2(win2)[:, :, 0]
        self._buffers_in = [win1[:, :, 1:], win2[:, :, 1:]]
        return out


class PMnet(RetargetModel):
    """Pose-movement network retargeter."""

    name = "pmnet"

    def __init__(
        self,
        hidden_size: int = 512,
        num_layers: int = 4,
        movement_channels: int = 128,
        movement_kernel: int = 3,
        dropout: float = 0.2,
        causal_movement: bool = True,
    ) -> None:
        super().__init__()
        self.hidden_size = hidden_size
        self.num_layers = num_layers
        self.movement_channels = movement_channels
        self.movement_kernel = movement_kernel
        self.dropout = dropout
        self.causal_movement = causal_movement
        j = self.num_joints
        self.pose_norm = Standardizer(3 * j)
        self.offset_norm = Standardizer(3 * j)
        self.movement_norm = Standardizer(ROOT_VEL_DIM)
        layers: list[nn.Module] = []
        width = 3 * j
        for _ in range(num_layers):
            layers += [nn.Linear(width, hidden_size), nn.ReLU(), nn.Dropout(dropout)]
            width = hidden_size
        self.pose_encoder = nn.Sequential(*layers)
        self.to_quat = nn.Linear(hidden_size, 4 * j)
        self.to_delta = nn.Linear(hidden_size + 3 * j, 4 * j)
        with torch.no_grad():
            for head in (self.to_quat, self.to_delta):
                head.weight.mul_(_QUAT_INIT_SCALE)
                head.bias.copy_(qt.identity((j,)).flatten())
        self.movement = MovementRegressor(
            movement_channels, movement_kernel, dropout, causal_movement
        )
        self._frame_consts: _FrameConstants | None = None

    def config(self) -> dict[str, Any]:
        return {
            "hidden_size": self.hidden_size,
            "num_layers": self.num_layers,
            "movement_channels": self.movement_channels,
            "movement_kernel": self.movement_kernel,
            "dropout": self.dropout,
            "causal_movement": self.causal_movement,
        }

    def fit_normalization(self, features: MotionFeatures, offsets: Tensor) -> None:
        self.pose_norm.fit(features.pose_flat)
        self.offset_norm.fit(offsets.flatten(-2))
        self.movement_norm.fit(normalize_movement(features.root_vel, pmnet_scale(offsets)))

    def encode_pose(self, pose_flat: Tensor) -> Tensor:
        """φ = F_P(p) for local poses (…, 3J) in metres."""
        x = self.pose_norm(pose_flat)
        if self.training:
            encoded: Tensor = self.pose_encoder(x)
            return encoded
        # Inference: the same layers without module dispatch and identity dropouts (the online
        # path's per-frame budget is a fraction of a millisecond).
        for layer in self.pose_encoder:
            if isinstance(layer, nn.Linear):
                x = torch.relu(nnf.linear(x, layer.weight, layer.bias))
        return x

    def _pose(self, phi: Tensor, tgt_offsets_flat: Tensor) -> tuple[Tensor, Tensor]:
        """(q_A, q_B) from φ (…, H) and target offsets broadcast to (…, 3J)."""
        shape = (*phi.shape[:-1], self.num_joints, 4)
        q_a = qt.normalize(self.to_quat(phi).view(shape))
        delta_in = torch.cat([phi, self.offset_norm(tgt_offsets_flat)], dim=-1)
        delta = qt.normalize(self.to_delta(delta_in).view(shape))
        return q_a, qt.normalize(qt.mul(q_a, delta))

    def _movement_out(self, nv_b: Tensor, tgt_offsets: Tensor) -> Tensor:
        return denormalize_movement(self.movement_norm.inverse(nv_b), pmnet_scale(tgt_offsets))

    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        t = src.root_vel.shape[1]
        phi_a = self.encode_pose(src.pose_flat)
        tgt_flat = tgt_offsets.flatten(-2)[:, None].expand(-1, t, -1)
        q_a, q_b = self._pose(phi_a, tgt_flat)
        nv_a = self.movement_norm(normalize_movement(src.root_vel, pmnet_scale(src_offsets)))
        vel_b = self._movement_out(self.movement(nv_a), tgt_offsets)
        return Prediction(local_quats=q_b, root_vel=vel_b, extras={"q_a": q_a, "phi_a": phi_a})

    def runtime(self) -> RuntimeModel | None:
        """The numpy step exists for the causal movement regressor only (as the torch one)."""
        if not self.causal_movement:
            return None
        from robot_retarget.runtime.model import RuntimeModel

        return RuntimeModel(name=self.name, architecture="pmnet", weights=self.export_weights())

    @torch.no_grad()
    def export_weights(self) -> PMnetWeights:
        """The parameters as numpy arrays (see :class:`PMnetWeights`)."""
        return PMnetWeights(
            pose_mean=to_numpy(self.pose_norm.mean),
            pose_std=to_numpy(self.pose_norm.std),
            offset_mean=to_numpy(self.offset_norm.mean),
            offset_std=to_numpy(self.offset_norm.std),
            movement_mean=to_numpy(self.movement_norm.mean),
            movement_std=to_numpy(self.movement_norm.std),
            encoder_layers=linear_pairs(self.pose_encoder),
            to_quat=layer_pair(self.to_quat),
            to_delta=layer_pair(self.to_delta),
            conv1=layer_pair(self.movement.conv1),
            conv2=layer_pair(self.movement.conv2),
        )

    def reset_state(self) -> None:
        self.movement.reset()
        self._frame_consts = None

    def _constants(self, src_offsets: Tensor, tgt_offsets: Tensor) -> _FrameConstants:
        """Per-skeleton terms of the online path, computed once per live sequence."""
        c = self._frame_consts
        if c is None or not (torch.equal(c.src, src_offsets) and torch.equal(c.tgt, tgt_offsets)):
            h = self.hidden_size
            offset_in = self.offset_norm(tgt_offsets.flatten(-2))
            c = _FrameConstants(
                src=src_offsets.clone(),
                tgt=tgt_offsets.clone(),
                scale_src=pmnet_scale(src_offsets),
                scale_tgt=pmnet_scale(tgt_offsets),
                # F_Δ([φ, ref_B]) = W_φ φ + (W_ref ref_B + b): the bracket is fixed per target.
                delta_weight=self.to_delta.weight[:, :h],
                delta_bias=nnf.linear(offset_in, self.to_delta.weight[:, h:], self.to_delta.bias),
            )
            self._frame_consts = c
        return c

    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        c = self._constants(src_offsets, tgt_offsets)
        phi_a = self.encode_pose(src.local_pos.flatten(-2))
        shape = (phi_a.shape[0], self.num_joints, 4)
        q_a = qt.normalize(self.to_quat(phi_a).view(shape))
        delta = qt.normalize((nnf.linear(phi_a, c.delta_weight) + c.delta_bias).view(shape))
        q_b = hamilton(q_a, delta)
        nv_a = self.movement_norm(normalize_movement(src.root_vel, c.scale_src))
        nv_b = self.movement_norm.inverse(self.movement.step(nv_a))
        return q_b, denormalize_movement(nv_b, c.scale_tgt)


@dataclass(frozen=True)
class _FrameConstants:
    src: Tensor
    tgt: Tensor
    scale_src: Tensor
    scale_tgt: Tensor
    delta_weight: Tensor
    delta_bias: Tensor


@torch.inference_mode(False)
def _hamilton_table() -> Tensor:
    """(16, 4) table H with (a ⊗ b) = (a bᵀ).flatten() @ H (the Hamilton product)."""
    return torch.tensor(product_table(), dtype=torch.float32)


_HAMILTON = _hamilton_table()


def hamilton(a: Tensor, b: Tensor) -> Tensor:
    """a ⊗ b for same-shaped quaternions (…, 4) in two tensor ops (the online path's q_A ⊗ Δq).

    Equals :func:`robot_retarget.nn.quaternion_torch.mul` (tested); cheaper per call for the
    single-frame path, where per-op overhead dominates.
    """
    outer = (a[..., :, None] * b[..., None, :]).flatten(-2)
    return outer @ _HAMILTON.to(outer)


def normalize_movement(root_vel: Tensor, scale: Tensor) -> Tensor:
    """Divide the x, y, z root velocity (B, …, 4) by each sample's scale S (B,)."""
    s = scale.view((-1,) + (1,) * (root_vel.ndim - 1))
    return torch.cat([root_vel[..., :3] / s, root_vel[..., 3:]], dim=-1)


def denormalize_movement(norm_vel: Tensor, scale: Tensor) -> Tensor:
    """Inverse of :func:`normalize_movement`: multiply x, y, z by S (B,)."""
    s = scale.view((-1,) + (1,) * (norm_vel.ndim - 1))
    return torch.cat([norm_vel[..., :3] * s, norm_vel[..., 3:]], dim=-1)
