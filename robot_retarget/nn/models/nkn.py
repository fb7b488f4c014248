"""Neural Kinematic Networks (Villegas et al., CVPR 2018): encoder/decoder GRUs + FK layer.

Per frame t (paper eqs. 2–7):

    h_enc_t = GRU_enc(x_t, h_enc_{t−1})                       x_t = [p_t, v_t]
    h_dec_t = GRU_dec([x̂_{t−1}, h_enc_t, s̄], h_dec_{t−1})     s̄ = target rest offsets
    q̂_t = W_p h_dec_t / ‖·‖ (per joint),  v̂_t = W_v h_dec_t,  p̂_t = FK(q̂_t, s̄)

Online by construction: frame t sees frames ≤ t only, and :meth:`NKN.step` runs the same cells
with carried hidden states (no buffering, no latency). Paper hyper-parameters (appendix E):
2-layer GRUs with 512 hidden units; quaternion outputs initialised near the identity.

Our choices where the paper is silent: x̂_0 (the decoder's first feedback) is zero in normalised
units; inputs x_t, the feedback x̂ and s̄ are standardised with statistics fitted from training
data (:meth:`fit_normalization`); W_v predicts velocities in those normalised units.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import (
    ROOT_VEL_DIM,
    FrameFeatures,
    FrameKinematics,
    MotionFeatures,
)
from robot_retarget.nn.models.base import Prediction, RetargetModel
from robot_retarget.nn.models.normalization import Standardizer

Tensor = torch.Tensor

# Initial weight scale of W_p: outputs start within ~1e-2 of the identity quaternion.
_QUAT_INIT_SCALE = 1e-2


class NKN(RetargetModel):
    """Neural Kinematic Network retargeter (online, causal)."""

    name = "nkn"

    def __init__(self, hidden_size: int = 512, num_layers: int = 2) -> None:
        super().__init__()
        self.hidden_size = hidden_size
        self.num_layers = num_layers
        j = self.num_joints
        x_dim = 3 * j + ROOT_VEL_DIM
        self.pose_norm = Standardizer(3 * j)
        self.vel_norm = Standardizer(ROOT_VEL_DIM)
        self.offset_norm = Standardizer(3 * j)
        self.encoder = nn.GRU(x_dim, hidden_size, num_layers, batch_first=True)
        self.decoder = nn.GRU(
            x_dim + hidden_size + 3 * j, hidden_size, num_layers, batch_first=True
        )
        self.to_quat = nn.Linear(hidden_size, 4 * j)
        self.to_vel = nn.Linear(hidden_size, ROOT_VEL_DIM)
        with torch.no_grad():
            self.to_quat.weight.mul_(_QUAT_INIT_SCALE)
            self.to_quat.bias.copy_(qt.identity((j,)).flatten())
        self._frame_fk = FrameKinematics(self.parents)
        self._h_enc: Tensor | None = None
        self._h_dec: Tensor | None = None
        self._prev_x: Tensor | None = None

    def config(self) -> dict[str, Any]:
        return {"hidden_size": self.hidden_size, "num_layers": self.num_layers}

    def fit_normalization(self, features: MotionFeatures, offsets: Tensor) -> None:
        self.pose_norm.fit(features.pose_flat)
        self.vel_norm.fit(features.root_vel)
        self.offset_norm.fit(offsets.flatten(-2))

    def _x(self, pose_flat: Tensor, vel: Tensor) -> Tensor:
        return torch.cat([self.pose_norm(pose_flat), self.vel_norm(vel)], dim=-1)

    def _decode(
        self, dec_in: Tensor, h_dec: Tensor | None, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        """One decoder step: (quats (B,J,4), vel (B,4), pos (B,J,3), next x̂, hidden)."""
        out, h_dec = self.decoder(dec_in[:, None], h_dec)
        h = out[:, 0]
        quats = qt.normalize(self.to_quat(h).view(-1, self.num_joints, 4))
        vel = self.vel_norm.inverse(self.to_vel(h))
        # The FK layer, one frame at a time: the single-frame form (same result as fk_torch,
        # tested) costs a tenth of the tensor ops, in training and online alike.
        pos = self._frame_fk.positions(quats, tgt_offsets)[0]
        x_hat = self._x(pos.flatten(-2), vel)
        return quats, vel, pos, x_hat, h_dec

    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        b, t = src.root_vel.shape[:2]
        h_enc, _ = self.encoder(self._x(src.pose_flat, src.root_vel))
        s_bar = self.offset_norm(tgt_offsets.flatten(-2))
        x_hat = h_enc.new_zeros(b, self.encoder.input_size)
        h_dec: Tensor | None = None
        quats, vels, poss = [], [], []
        for i in range(t):
            dec_in = torch.cat([x_hat, h_enc[:, i], s_bar], dim=-1)
            q, v, p, x_hat, h_dec = self._decode(dec_in, h_dec, tgt_offsets)
            quats.append(q)
            vels.append(v)
            poss.append(p)
        return Prediction(
            local_quats=torch.stack(quats, 1),
            root_vel=torch.stack(vels, 1),
            local_pos=torch.stack(poss, 1),
        )

    def reset_state(self) -> None:
        self._h_enc = None
        self._h_dec = None
        self._prev_x = None

    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        x = self._x(src.local_pos.flatten(-2), src.root_vel)
        enc_out, self._h_enc = self.encoder(x[:, None], self._h_enc)
        prev = self._prev_x if self._prev_x is not None else torch.zeros_like(x)
        dec_in = torch.cat([prev, enc_out[:, 0], self.offset_norm(tgt_offsets.flatten(-2))], -1)
        quats, vel, _, self._prev_x, self._h_dec = self._decode(dec_in, self._h_dec, tgt_offsets)
        return quats, vel
