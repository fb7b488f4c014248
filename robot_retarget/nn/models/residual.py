"""Residual retargeter: the source's own rotations, denoised, times a learned correction.

PMnet writes the target pose as q_B = q_A ⊗ Δq, but regresses q_A from joint positions,
which loses every bone's twist and costs its reconstruction error before any retargeting
happens. Our sources *are* rotations (BVH, live rotation streams), so this model keeps PMnet's
factorisation and takes q_A from the input instead of regressing it:

    q̃_A = D(q_A,t, q_A,t−1 … q_A,t−K)          causal denoiser, per joint
    Δq  = exp(c · tanh(F_Δ([p̃_A / h_A, 6D(q̃_A), ref_A / h_A, ref_B / h_B]) / c))
    q_B = L(q̃_A ⊗ Δq)
    v_B = F_v(v_A) · h_B / h_A,   ω_B = ω_A

- D is a small network shared by all joints (with a joint code) that, from the rotations of
  the last K frames relative to the current one (r_k = log(q_t⁻¹ ⊗ q_{t−k})), predicts K
  weights w_k and returns q_t ⊗ exp(Σ w_k r_k): a learned, input-dependent causal filter. With
  w = 0 it is the identity; w = (1, 0, …) holds the previous frame (a dropped joint);
  w = (2, −1, …) extrapolates it; small positive weights smooth jitter. It is trained against
  the clean motion on corrupted input (robot_retarget.nn.corruption).
- F_Δ (an MLP) sees the denoised pose as root-relative positions (FK on the source skeleton)
  and 6D rotations, and both skeletons' rest offsets divided by their heights: the correction
  depends on proportions, not size. It outputs a rotation vector whose components are capped
  at ±c (``max_correction_deg``, 30°), and its inputs are standardised with spread floors, so
  a pose unlike any in training cannot swing a joint around.
- The root moves as copy-scaled's (velocity × height ratio), through F_v: a learned causal
  FIR filter on the velocity (trained on noisy input against the clean path) whose taps sum to
  one, so it smooths a jittery root without a
  bias that the integration would turn into drift (a free residual network did exactly that
  in our first runs: 0.2 % of a stride per frame became metres over a long clip). The turning
  rate is copied (a heading drift would turn the whole motion away from the source).

- L is the foot lock (robot_retarget.nn.models.foot_lock): where the performer's ankle is
  planted, leg IK holds the target's ankle where it landed. Without it the corrections and the
  denoiser's filtering made the feet slide more than copy-scaled's (cross-validated: 0.31 vs
  0.16 leg lengths/s). It has no parameters; training sees its output, so the losses score
  the pose the robot gets. ``foot_lock=False`` leaves it out (checkpoints from before it).

Every last layer starts at zero, so an untrained model is copy-scaled with its feet locked;
training moves it only where its losses (robot_retarget.nn.retarget_losses) say the copy is
wrong. Everything is causal: :meth:`step` keeps the last K source frames, F_v's last
velocities and the lock's anchors.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import (
    FrameFeatures,
    FrameKinematics,
    MotionFeatures,
    local_positions,
    skeleton_height,
)
from robot_retarget.nn.models.base import Prediction, RetargetModel
from robot_retarget.nn.models.foot_lock import FootLock
from robot_retarget.nn.models.normalization import Standardizer
from robot_retarget.nn.models.pmnet import hamilton
from robot_retarget.nn.models.weight_export import layer_pair, linear_pairs, to_numpy
from robot_retarget.nn.retarget_losses import limb_lengths
from robot_retarget.runtime.residual_weights import ResidualWeights

if TYPE_CHECKING:
    from robot_retarget.runtime.model import RuntimeModel

Tensor = torch.Tensor

# Relative rotations between neighbouring frames are a few hundredths of a radian; scaled so
# the denoiser's inputs are of order one.
_REL_SCALE = 10.0


def _zero_last(layer: nn.Linear | nn.Conv1d) -> None:
    with torch.no_grad():
        layer.weight.zero_()
        if layer.bias is not None:
            layer.bias.zero_()


def _past_frames(q: Tensor, history: int) -> Tensor:
    """(B, T, J, K, 4): frames t−1 … t−K of rotations (B, T, J, 4), frame 0 repeated before t=0."""
    t = q.shape[1]
    padded = torch.cat([q[:, :1].expand(-1, history, -1, -1), q], dim=1)
    return torch.stack([padded[:, history - k : history - k + t] for k in range(1, history + 1)], 3)


class CausalRotationDenoiser(nn.Module):
    """D: a learned causal filter on every non-root joint's rotation (see the module docs)."""

    joint_code: Tensor

    def __init__(self, num_joints: int, history: int = 4, hidden: int = 64) -> None:
        super().__init__()
        if history < 1:
            raise ValueError(f"the denoiser needs a history of at least 1 frame, got {history}")
        self.history = history
        self.register_buffer("joint_code", torch.eye(num_joints))
        in_dim = 4 * history + 1 + num_joints
        self.net = nn.Sequential(
            nn.Linear(in_dim, hidden),
            nn.ReLU(),
            nn.Linear(hidden, hidden),
            nn.ReLU(),
            nn.Linear(hidden, history),
        )
        last = self.net[-1]
        assert isinstance(last, nn.Linear)
        _zero_last(last)
        self._past: Tensor | None = None

    def _filter(self, q_t: Tensor, past: Tensor) -> Tensor:
        """q_t (…, J, 4), past (…, J, K, 4) → filtered (…, J, 4); the root passes unchanged."""
        rel = qt.to_rotation_vector(qt.mul(qt.conjugate(q_t)[..., None, :], past))  # (…, J, K, 3)
        own = torch.linalg.vector_norm(qt.to_rotation_vector(q_t), dim=-1)  # (…, J)
        code = self.joint_code.expand(*q_t.shape[:-1], -1)
        feats = torch.cat(
            [
                (rel * _REL_SCALE).flatten(-2),
                torch.linalg.vector_norm(rel, dim=-1) * _REL_SCALE,
                own[..., None],
                code,
            ],
            dim=-1,
        )
        weights = self.net(feats)  # (…, J, K)
        correction = (weights[..., None] * rel).sum(dim=-2)
        filtered = qt.mul(q_t, qt.from_rotation_vector(correction))
        return torch.cat([q_t[..., :1, :], filtered[..., 1:, :]], dim=-2)

    def forward(self, q: Tensor) -> Tensor:
        """Denoised rotations (B, T, J, 4) of a clip."""
        return self._filter(q, _past_frames(q, self.history))

    def reset(self) -> None:
        self._past = None

    def step(self, q_t: Tensor) -> Tensor:
        """One frame (B, J, 4), equal to :meth:`forward`'s frame on the whole clip."""
        if self._past is None:
            self._past = q_t[..., None, :].expand(-1, -1, self.history, -1)
        out = self._filter(q_t, self._past)
        self._past = torch.cat([q_t[..., None, :], self._past[..., :-1, :]], dim=-2)
        return out


class CausalVelocityFilter(nn.Module):
    """F_v: v_out,t = Σ_k a_k v_t−k over the last ``taps`` frames, with Σ a_k = 1 and
    Σ k·a_k = 0.

    Unit gain: the integrated path cannot drift. Zero first moment: a steady velocity comes out
    unchanged, so the root does not lag behind a walking source (a filter free of this
    constraint learned a 1.6-frame lag). Parametrised as a = e₀ + P b with P the projection
    orthogonal to (1, …, 1) and (0, 1, …, K − 1), so any b keeps both, and b = 0 (the start)
    passes the velocity through. Needs 3 taps or more to smooth at all. Velocities before the
    first frame are zero (the features' frame-0 velocity is zero too).
    """

    projection: Tensor

    def __init__(self, taps: int = 5) -> None:
        super().__init__()
        if taps < 1:
            raise ValueError(f"the root filter needs at least 1 tap, got {taps}")
        self.taps = taps
        self.b = nn.Parameter(torch.zeros(taps))
        k = torch.arange(taps, dtype=torch.float32)
        basis = [torch.ones(taps)]
        if taps > 1:
            basis.append(k - k.mean())
        proj = torch.eye(taps)
        for u in basis:
            u = u / torch.linalg.vector_norm(u)
            proj = proj - u[:, None] * u[None, :]
        self.register_buffer("projection", proj, persistent=False)
        self._past: Tensor | None = None

    def weights(self) -> Tensor:
        """The taps a (taps,), a₀ for the current frame: Σ a = 1, Σ k·a_k = 0."""
        e0 = nnf.one_hot(torch.tensor(0), self.taps).to(self.b)
        return e0 + self.projection.to(self.b) @ self.b

    def forward(self, v: Tensor) -> Tensor:
        """Filtered velocities (B, T, C)."""
        a = self.weights()
        padded = nnf.pad(v, (0, 0, self.taps - 1, 0))
        t = v.shape[1]
        return sum(
            (a[k] * padded[:, self.taps - 1 - k : self.taps - 1 - k + t] for k in range(self.taps)),
            torch.zeros_like(v),
        )

    def reset(self) -> None:
        self._past = None

    def step(self, v: Tensor) -> Tensor:
        """One frame (B, C), equal to :meth:`forward`'s frame on the whole clip."""
        if self._past is None:
            self._past = v.new_zeros(v.shape[0], self.taps - 1, v.shape[-1])
        window = torch.cat([v[:, None], self._past], dim=1)  # newest first
        self._past = window[:, :-1]
        return (self.weights()[None, :, None] * window).sum(dim=1)


class ResidualRetargeter(RetargetModel):
    """Copy-scaled plus a learned denoiser and pose correction (see the module docstring)."""

    name = "residual"

    def __init__(
        self,
        hidden_size: int = 256,
        num_layers: int = 3,
        denoiser_history: int = 4,
        denoiser_hidden: int = 64,
        root_filter_taps: int = 5,
        max_correction_deg: float = 30.0,
        foot_lock: bool = True,
    ) -> None:
        super().__init__()
        self.hidden_size = hidden_size
        self.num_layers = num_layers
        self.denoiser_history = denoiser_history
        self.denoiser_hidden = denoiser_hidden
        self.root_filter_taps = root_filter_taps
        self.max_correction_deg = max_correction_deg
        self.foot_lock = foot_lock
        j = self.num_joints
        self.denoiser = CausalRotationDenoiser(j, denoiser_history, denoiser_hidden)
        # Spread floors (heights, 6D components, offsets / height): see Standardizer.
        self.pose_norm = Standardizer(3 * j, min_std=0.05)
        self.rot_norm = Standardizer(6 * j, min_std=0.05)
        self.offset_norm = Standardizer(3 * j, min_std=0.01)
        self._pose_dim = 9 * j  # positions and 6D rotations: the per-frame part of the input
        layers: list[nn.Module] = []
        width = self._pose_dim + 6 * j
        for _ in range(num_layers):
            layers += [nn.Linear(width, hidden_size), nn.ReLU()]
            width = hidden_size
        self.correction = nn.Sequential(*layers)
        self.to_delta = nn.Linear(hidden_size, 3 * j)
        _zero_last(self.to_delta)
        self.root_filter = CausalVelocityFilter(root_filter_taps)
        self.lock = FootLock() if foot_lock else None
        self._fk = FrameKinematics(self.parents)
        self._consts: _SkeletonConstants | None = None

    def config(self) -> dict[str, Any]:
        return {
            "hidden_size": self.hidden_size,
            "num_layers": self.num_layers,
            "denoiser_history": self.denoiser_history,
            "denoiser_hidden": self.denoiser_hidden,
            "root_filter_taps": self.root_filter_taps,
            "max_correction_deg": self.max_correction_deg,
            "foot_lock": self.foot_lock,
        }

    @classmethod
    def upgrade_config(cls, config: dict[str, Any]) -> dict[str, Any]:
        # Checkpoints from before the foot lock ran without it.
        return {"foot_lock": False, **config}

    def fit_normalization(self, features: MotionFeatures, offsets: Tensor) -> None:
        h = skeleton_height(offsets, self.parents)
        self.pose_norm.fit(features.pose_flat / h[:, None, None])
        self.rot_norm.fit(qt.to_rotation_6d(features.local_quats).flatten(-2))
        self.offset_norm.fit(offsets.flatten(-2) / h[:, None])

    def runtime(self) -> RuntimeModel | None:
        from robot_retarget.runtime.model import RuntimeModel

        return RuntimeModel(name=self.name, architecture="residual", weights=self.export_weights())

    @torch.no_grad()
    def export_weights(self) -> ResidualWeights:
        """The parameters as numpy arrays (see :class:`ResidualWeights`)."""
        return ResidualWeights(
            denoiser_layers=linear_pairs(self.denoiser.net),
            denoiser_history=self.denoiser.history,
            pose_mean=to_numpy(self.pose_norm.mean),
            pose_std=to_numpy(self.pose_norm.std),
            rot_mean=to_numpy(self.rot_norm.mean),
            rot_std=to_numpy(self.rot_norm.std),
            offset_mean=to_numpy(self.offset_norm.mean),
            offset_std=to_numpy(self.offset_norm.std),
            correction_layers=linear_pairs(self.correction),
            to_delta=layer_pair(self.to_delta),
            max_correction_rad=math.radians(self.max_correction_deg),
            root_taps=to_numpy(self.root_filter.weights()),
            foot_lock=self.lock is not None,
        )

    # The per-skeleton terms of F_Δ are cached between frames; anything that can change the
    # weights, their dtype or device drops the cache.
    def train(self, mode: bool = True) -> ResidualRetargeter:
        self._consts = None
        return super().train(mode)

    def _apply(self, fn: Any, recurse: bool = True) -> ResidualRetargeter:
        self._consts = None
        return super()._apply(fn, recurse)  # type: ignore[no-untyped-call]

    def load_state_dict(
        self, state_dict: Mapping[str, Any], strict: bool = True, assign: bool = False
    ) -> Any:
        self._consts = None
        return super().load_state_dict(state_dict, strict, assign)

    # --- shared by the clip and the frame path ---------------------------------------------

    def _constants(self, src_offsets: Tensor, tgt_offsets: Tensor) -> _SkeletonConstants:
        """Per-skeleton-pair terms: heights and the offsets' share of F_Δ's first layer."""
        c = self._consts
        if (
            c is not None
            and not self.training
            and torch.equal(c.src, src_offsets)
            and torch.equal(c.tgt, tgt_offsets)
        ):
            return c
        h_src = skeleton_height(src_offsets, self.parents)
        h_tgt = skeleton_height(tgt_offsets, self.parents)
        first = self.correction[0]
        assert isinstance(first, nn.Linear)
        ref_a = self.offset_norm(src_offsets.flatten(-2) / h_src[:, None])
        ref_b = self.offset_norm(tgt_offsets.flatten(-2) / h_tgt[:, None])
        k = 3 * self.num_joints
        w_ref = first.weight[:, self._pose_dim :]
        bias = nnf.linear(ref_a, w_ref[:, :k]) + nnf.linear(ref_b, w_ref[:, k:], first.bias)
        c = _SkeletonConstants(
            src=src_offsets.clone(),
            tgt=tgt_offsets.clone(),
            h_src=h_src,
            h_tgt=h_tgt,
            leg_src=limb_lengths(src_offsets)[1],
            pose_weight=first.weight[:, : self._pose_dim],
            bias=bias,
        )
        if not self.training:
            self._consts = c
        return c

    def _delta(self, q: Tensor, pos: Tensor, c: _SkeletonConstants) -> Tensor:
        """Δq (…, J, 4) for denoised rotations q (…, J, 4) and their positions (…, J, 3)."""
        lead = q.shape[:-2]
        h = c.h_src.view(-1, *([1] * (len(lead) - 1)), 1)
        pose = torch.cat(
            [
                self.pose_norm(pos.flatten(-2) / h),
                self.rot_norm(qt.to_rotation_6d(q).flatten(-2)),
            ],
            dim=-1,
        )
        bias = c.bias.view(c.bias.shape[0], *([1] * (len(lead) - 1)), -1)
        x = torch.relu(nnf.linear(pose, c.pose_weight) + bias)
        for layer in list(self.correction)[2:]:
            x = layer(x)
        # Δq = exp(c · tanh(u / c)): every rotation-vector component stays within ±c, so no
        # input, however far from the training data, turns a joint by more than √3 · c.
        cap = math.radians(self.max_correction_deg)
        u = self.to_delta(x).view(*lead, self.num_joints, 3)
        return qt.from_rotation_vector(cap * torch.tanh(u / cap))

    def _root_velocity(
        self, root_vel: Tensor, filtered_xyz: Tensor, c: _SkeletonConstants
    ) -> Tensor:
        ratio = (c.h_tgt / c.h_src).view((-1,) + (1,) * (root_vel.ndim - 1))
        return torch.cat([filtered_xyz * ratio, root_vel[..., 3:]], dim=-1)

    # --- clip path ---------------------------------------------------------------------------

    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        c = self._constants(src_offsets, tgt_offsets)
        q_den = self.denoiser(src.local_quats)
        pos_den = local_positions(q_den, src_offsets, self.parents)
        q_b = qt.normalize(hamilton(q_den, self._delta(q_den, pos_den, c)))
        vel = self._root_velocity(src.root_vel, self.root_filter(src.root_vel[..., :3]), c)
        if self.lock is not None:
            q_b = self.lock(q_b, vel, tgt_offsets, src.local_pos, src.root_vel, c.leg_src)
        return Prediction(
            local_quats=q_b,
            root_vel=vel,
            extras={"q_denoised": q_den, "pos_denoised": pos_den},
        )

    # --- frame path --------------------------------------------------------------------------

    def reset_state(self) -> None:
        self.denoiser.reset()
        self.root_filter.reset()
        if self.lock is not None:
            self.lock.reset()
        self._consts = None

    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        c = self._constants(src_offsets, tgt_offsets)
        q_den = self.denoiser.step(src.local_quats)
        pos_den, _ = self._fk.positions(q_den, src_offsets)
        q_b = qt.normalize(hamilton(q_den, self._delta(q_den, pos_den, c)))
        vel = self._root_velocity(src.root_vel, self.root_filter.step(src.root_vel[..., :3]), c)
        if self.lock is not None:
            q_b = self.lock.step(q_b, vel, tgt_offsets, src.local_pos, src.root_vel, c.leg_src)
        return q_b, vel


@dataclass(frozen=True)
class _SkeletonConstants:
    src: Tensor
    tgt: Tensor
    h_src: Tensor
    h_tgt: Tensor
    leg_src: Tensor
    pose_weight: Tensor
    bias: Tensor
