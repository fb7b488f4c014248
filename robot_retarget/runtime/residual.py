"""numpy twin of the residual model's online step (no torch on the live path).

:class:`robot_retarget.nn.models.residual.ResidualRetargeter` through torch costs ~0.5 ms per
frame, nearly all of it per-op dispatch on tensors of a few hundred numbers. The live loop has a
fraction of a millisecond for the whole chain, so :class:`FastResidualRetargeter` copies the
trained weights into float64 arrays once and runs the same arithmetic in numpy, step for step
as ``RetargetModel.step``: heading removal and root velocity as ``FeatureStream``, the causal
denoiser, forward kinematics by pointer jumping (as ``FrameKinematics``), the pose correction
with its per-skeleton bias folded in, the root filter and the integration. Its output equals
:class:`robot_retarget.nn.inference.OnlineRetargeter`'s to float32 rounding (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.runtime.copy import rest_height_m
from robot_retarget.runtime.frame import (
    NUM_JOINTS,
    FrameStream,
    TreeKinematics,
    check_frame,
    check_offsets,
    f32_layer,
    from_rotvec,
    left_matrices,
    matrices,
    qmul,
    rotvec,
)
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS

_J = NUM_JOINTS
_REL_SCALE = 10.0  # as robot_retarget.nn.models.residual


@dataclass(frozen=True)
class ResidualWeights:
    """A residual model's parameters as float64 numpy arrays, for numpy twins of its step
    (here): every Linear as (weight, bias) in order."""

    denoiser_layers: tuple[tuple[FloatArray, FloatArray], ...]
    denoiser_history: int
    pose_mean: FloatArray
    pose_std: FloatArray
    rot_mean: FloatArray
    rot_std: FloatArray
    offset_mean: FloatArray
    offset_std: FloatArray
    correction_layers: tuple[tuple[FloatArray, FloatArray], ...]
    to_delta: tuple[FloatArray, FloatArray]
    max_correction_rad: float
    root_taps: FloatArray


class FastResidualRetargeter:
    """Online residual model on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,)."""

    def __init__(
        self,
        weights: ResidualWeights,
        source_offsets: npt.ArrayLike,
        target_offsets: npt.ArrayLike,
    ) -> None:
        src = check_offsets("source_offsets", source_offsets)
        tgt = check_offsets("target_offsets", target_offsets)
        self._src = src
        self._kin = TreeKinematics(CANONICAL_PARENTS)
        self._stream = FrameStream()
        h_src, h_tgt = rest_height_m(src), rest_height_m(tgt)
        self._ratio = h_tgt / h_src
        w = weights
        self._history = w.denoiser_history
        # The joint one-hot code's share of the denoiser's first layer is a per-joint bias.
        (d0, e0), *self._den_rest = w.denoiser_layers
        n_feat = 4 * self._history + 1
        self._den_first = (d0[:, :n_feat].T.copy(), e0[None] + d0[:, n_feat:].T)
        w0, b0 = w.correction_layers[0]
        pose_dim = 9 * _J
        k = 3 * _J
        ref_a = (src.reshape(-1) / h_src - w.offset_mean) / w.offset_std
        ref_b = (tgt.reshape(-1) / h_tgt - w.offset_mean) / w.offset_std
        # The skeletons' share of the first layer is fixed for this pair, and the input
        # standardisation folds into it too: W (x − μ)/σ = (W/σ) x − (W/σ) μ.
        mean = np.concatenate([w.pose_mean, w.rot_mean])
        std = np.concatenate([w.pose_std, w.rot_std])
        scale = np.concatenate([np.full(3 * _J, 1.0 / h_src), np.ones(6 * _J)])
        w_pose = w0[:, :pose_dim] / std
        first_bias = (
            b0
            + w0[:, pose_dim : pose_dim + k] @ ref_a
            + w0[:, pose_dim + k :] @ ref_b
            - w_pose @ mean
        )
        # The correction MLP runs in float32, as the torch model does (faster matrix products).
        self._first = f32_layer((w_pose * scale, first_bias))
        self._hidden = [f32_layer(layer) for layer in w.correction_layers[1:]]
        self._to_delta = f32_layer(w.to_delta)
        self._max_correction = w.max_correction_rad
        self._root_taps = w.root_taps
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._past: FloatArray | None = None
        self._vel_past = np.zeros((len(self._root_taps) - 1, 3))
        self._stream.reset()

    def _denoise(self, q: FloatArray) -> FloatArray:
        if self._past is None:
            self._past = np.repeat(q[:, None], self._history, axis=1)
        conj = q * np.array([1.0, -1.0, -1.0, -1.0])
        # q_t⁻¹ ⊗ q_t−k for every k at once: one batched (K, 4) @ (4, 4) per joint.
        rel = rotvec(self._past @ left_matrices(conj).transpose(0, 2, 1))  # (J, K, 3)
        own = 2.0 * np.arctan2(np.sqrt(np.sum(q[:, 1:] ** 2, axis=-1)), np.abs(q[:, 0]))
        feats = np.concatenate(
            [
                rel.reshape(_J, -1) * _REL_SCALE,
                np.sqrt(np.sum(rel * rel, axis=-1)) * _REL_SCALE,
                own[:, None],
            ],
            axis=-1,
        )
        w_first, b_first = self._den_first
        x = feats @ w_first + b_first
        for w, b in self._den_rest:
            x = np.maximum(x, 0.0) @ w.T + b
        correction = np.sum(x[:, :, None] * rel, axis=1)
        out = qmul(q, from_rotvec(correction))
        out[0] = q[0]
        self._past = np.concatenate([q[:, None], self._past[:, :-1]], axis=1)
        return out

    def _delta(self, q: FloatArray) -> FloatArray:
        rot = matrices(q)
        pos = self._kin.positions(rot, self._src)
        six = rot[:, :, :2].transpose(0, 2, 1)  # per joint: column 0, then column 1 (6D)
        x = np.concatenate([pos.reshape(-1), six.reshape(-1)]).astype(np.float32)
        w, b = self._first
        x = np.maximum(w @ x + b, 0.0)
        for w, b in self._hidden:
            x = np.maximum(w @ x + b, 0.0)
        w, b = self._to_delta
        cap = self._max_correction
        u = (w @ x + b).astype(np.float64).reshape(_J, 3)
        return from_rotvec(cap * np.tanh(u / cap))

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q, root = check_frame(local_quats, root_pos)
        vel, dyaw = self._stream.push(q, root)  # q is heading-free from here
        q_den = self._denoise(q)
        q_b = qmul(q_den, self._delta(q_den))
        q_b /= np.linalg.norm(q_b, axis=-1, keepdims=True)
        window = np.concatenate([vel[None], self._vel_past], axis=0)  # newest first
        self._vel_past = window[:-1]
        out_pos, out_yaw = self._stream.integrate(self._root_taps @ window * self._ratio, dyaw)
        return self._stream.apply_heading(q_b, out_yaw), out_pos
