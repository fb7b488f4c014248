"""numpy twin of PMnet's online step (no torch on the live path).

PMnet per frame (robot_retarget.nn.models.pmnet): the source's heading-free local pose through
the pose encoder F_P, q_A = F_q(φ_A), Δq = F_Δ([φ_A, ref_B]) with the target's share of F_Δ
folded into a bias, q_B = q_A ⊗ Δq, and the causal movement regressor F_M on the
scale-normalised root velocity, stepped with buffers of its last k − 1 inputs per layer. Its
output equals :class:`robot_retarget.nn.inference.OnlineRetargeter`'s to float32 rounding
(tested). Only the causal movement regressor has an online path (as in torch).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.runtime.frame import (
    FrameStream,
    TreeKinematics,
    check_frame,
    check_offsets,
    f32_layer,
    matrices,
    qmul,
)
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint

# PMnet eq. 6: the scale factor S sums the bone lengths of the root, spine, neck and left-leg
# joints. Their N_s only rescales Mixamo centimetres; our offsets are metres, so N_s = 1.
PMNET_SCALE_JOINTS: tuple[int, ...] = (
    Joint.Hips, Joint.Spine, Joint.Spine1, Joint.Spine2, Joint.Neck,
    Joint.LeftUpLeg, Joint.LeftLeg, Joint.LeftFoot,
)  # fmt: skip


@dataclass(frozen=True)
class PMnetWeights:
    """A PMnet's parameters as float64 numpy arrays, for the numpy twin of its online step
    (here); Linear layers as (weight, bias), convolutions as
    (weight (out, in, k), bias)."""

    pose_mean: FloatArray
    pose_std: FloatArray
    offset_mean: FloatArray
    offset_std: FloatArray
    movement_mean: FloatArray
    movement_std: FloatArray
    encoder_layers: tuple[tuple[FloatArray, FloatArray], ...]
    to_quat: tuple[FloatArray, FloatArray]
    to_delta: tuple[FloatArray, FloatArray]
    conv1: tuple[FloatArray, FloatArray]
    conv2: tuple[FloatArray, FloatArray]


def pmnet_scale(offsets: FloatArray) -> float:
    """PMnet's S (eq. 6, N_s = 1): bone lengths of the root, spine, neck and left leg."""
    return float(np.linalg.norm(offsets[list(PMNET_SCALE_JOINTS)], axis=-1).sum())


def _unit(q: FloatArray) -> FloatArray:
    return np.asarray(q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12))


class FastPMnetRetargeter:
    """Online PMnet on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,)."""

    def __init__(
        self, weights: PMnetWeights, source_offsets: npt.ArrayLike, target_offsets: npt.ArrayLike
    ) -> None:
        src = check_offsets("source_offsets", source_offsets)
        tgt = check_offsets("target_offsets", target_offsets)
        self._src = src
        self._kin = TreeKinematics(CANONICAL_PARENTS)
        self._stream = FrameStream()
        w = weights
        self._pose_mean, self._pose_std = w.pose_mean, w.pose_std
        # The matrix–vector products run in float32, as the torch model does: 4× faster than
        # float64 for 512-wide layers, whose weights then fit the cache.
        self._encoder = [f32_layer(layer) for layer in w.encoder_layers]
        self._to_quat = f32_layer(w.to_quat)
        h = self._encoder[-1][0].shape[0]
        wd, bd = w.to_delta
        ref_b = (tgt.reshape(-1) - w.offset_mean) / w.offset_std
        # F_Δ([φ, ref_B]) = W_φ φ + (W_ref ref_B + b): the bracket is fixed for this target.
        self._delta = f32_layer((wd[:, :h], bd + wd[:, h:] @ ref_b))
        self._move_mean, self._move_std = w.movement_mean, w.movement_std
        self._conv1, self._conv2 = w.conv1, w.conv2
        self._k = self._conv1[0].shape[-1]
        self._scale_src = pmnet_scale(src)
        self._scale_tgt = pmnet_scale(tgt)
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._stream.reset()
        k = self._k - 1
        self._buf1 = np.zeros((self._conv1[0].shape[1], k))
        self._buf2 = np.zeros((self._conv2[0].shape[1], k))

    def _movement(self, nv: FloatArray) -> FloatArray:
        """F_M's step: (4,) normalised movement in → (4,) out, as MovementRegressor.step."""
        w1, b1 = self._conv1
        w2, b2 = self._conv2
        win1 = np.concatenate([self._buf1, nv[:, None]], axis=1)
        h = np.einsum("oik,ik->o", w1, win1) + b1
        h = np.where(h > 0.0, h, 0.2 * h)  # leaky ReLU
        win2 = np.concatenate([self._buf2, h[:, None]], axis=1)
        self._buf1, self._buf2 = win1[:, 1:], win2[:, 1:]
        return np.asarray(np.einsum("oik,ik->o", w2, win2) + b2)

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q, root = check_frame(local_quats, root_pos)
        vel, dyaw = self._stream.push(q, root)  # q is heading-free from here
        pose = self._kin.positions(matrices(q), self._src).reshape(-1)
        phi = ((pose - self._pose_mean) / self._pose_std).astype(np.float32)
        for w, b in self._encoder:
            phi = np.maximum(w @ phi + b, 0.0)
        wq, bq = self._to_quat
        q_a = _unit((wq @ phi + bq).astype(np.float64).reshape(-1, 4))
        wd, bd = self._delta
        q_b = qmul(q_a, _unit((wd @ phi + bd).astype(np.float64).reshape(-1, 4)))
        move = np.concatenate([vel / self._scale_src, [dyaw]])
        out = self._movement((move - self._move_mean) / self._move_std)
        out = out * self._move_std + self._move_mean
        out_pos, out_yaw = self._stream.integrate(out[:3] * self._scale_tgt, float(out[3]))
        return self._stream.apply_heading(q_b, out_yaw), out_pos
