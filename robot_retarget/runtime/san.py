"""numpy twin of SAN's canonical path (robot_retarget.nn.models.san): the causal online step.

The live path sends canonical joints, so the step runs the canonical encoder and the decoder.
Per frame: four skeletal convolutions, each a :class:`~robot_retarget.runtime.ring_conv.RingConv`
(one matrix–vector product over its last k inputs), with skeletal pooling between them. Three
things are folded once per (performer, robot) pair, so they cost nothing per frame:

- the static features (the skeletons' offsets through the static encoders) are constant over
  time, so their columns of every kernel, summed over the taps, become part of the bias;
- each unpooling copies a coarse armature's features to its finer ones, a linear map that is
  folded into the next kernel (fewer columns: 224 instead of 384 for the published sizes);
- the weights outside each armature's neighbourhood are zero in the dense kernels.

Products run in float32, as the torch model does; the step equals the torch model's online
step to float32 rounding (tests/runtime/test_san_runtime.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.runtime.copy import rest_height_m
from robot_retarget.runtime.frame import (
    F32Array,
    FrameStream,
    check_frame,
    check_offsets,
    unit_quaternions,
)
from robot_retarget.runtime.ring_conv import Conv, RingConv, leaky_relu
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

_J = len(CANONICAL_JOINTS)
_ROOT = 8  # root armature channels: heading-free root rotation (4) + root movement (4)
_IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class SANWeights:
    """The canonical path of a trained SAN, dense (zeros outside the neighbourhoods).

    ``armature_joints`` (A0 − 1,): the canonical joint of each non-root armature;
    ``pools``: the pooling matrices level 0 → 1 → 2 (A_{l+1}, A_l), means over groups;
    ``static`` / ``encoder`` / ``decoder``: the layers' kernels (out, in, k) and biases, the
    inputs of every dynamic layer ordered armature by armature, [dynamic, static] within one;
    ``shape`` = (static channels, causal 0/1).
    """

    armature_joints: FloatArray
    pools: tuple[FloatArray, FloatArray]
    static: tuple[Conv, Conv]
    encoder: tuple[Conv, Conv]
    decoder: tuple[Conv, Conv]
    root_mean: FloatArray
    root_std: FloatArray
    shape: tuple[float, float]

    @property
    def causal(self) -> bool:
        return bool(float(self.shape[1]))


def _static_features(w: SANWeights, offsets: FloatArray) -> list[FloatArray]:
    """Static features per level, (A_l, S), of a canonical skeleton's offsets (22, 3)."""
    joints = w.armature_joints.astype(np.int64)
    x = np.concatenate([np.zeros((1, 3)), offsets[joints] / rest_height_m(offsets)])
    out: list[FloatArray] = []
    for lvl, (kern, bias) in enumerate(w.static):
        if lvl > 0:
            x = w.pools[lvl - 1] @ x
        y = leaky_relu(kern[:, :, 0] @ x.reshape(-1) + bias)
        x = np.asarray(y, dtype=np.float64).reshape(x.shape[0], -1)
        out.append(x)
    return out


def _split_static(
    conv: Conv, widths: list[int], static: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """A kernel whose input per armature is [dynamic (widths[a]), static (S)]: the kernel on
    the dynamic columns only, and the bias with the static columns' constant share."""
    kern, bias = conv
    s = static.shape[1]
    keep: list[int] = []
    fixed = np.zeros(kern.shape[0])
    start = 0
    for a, width in enumerate(widths):
        keep.extend(range(start, start + width))
        cols = slice(start + width, start + width + s)
        fixed += kern[:, cols, :].sum(-1) @ static[a]
        start += width + s
    return kern[:, keep, :], bias + fixed


def _fold_unpool(kern: FloatArray, unpool: FloatArray, channels: int) -> FloatArray:
    """kernel (out, A_fine · C, k) after unpooling (A_fine, A_coarse) → (out, A_coarse · C, k)."""
    out, _, k = kern.shape
    fine = unpool.shape[0]
    per = kern.reshape(out, fine, channels, k)
    return np.einsum("ofck,fg->ogck", per, unpool).reshape(out, -1, k)


def _f32(a: FloatArray) -> F32Array:
    return np.ascontiguousarray(a, dtype=np.float32)


class FastSANRetargeter:
    """Online causal SAN on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,)."""

    def __init__(
        self, weights: SANWeights, source_offsets: npt.ArrayLike, target_offsets: npt.ArrayLike
    ) -> None:
        src = check_offsets("source_offsets", source_offsets)
        tgt = check_offsets("target_offsets", target_offsets)
        w = weights
        if not w.causal:
            raise ValueError(
                "this SAN is non-causal (it needs future frames) and has no online step; "
                "stream a causal SAN (train --model san, the default)"
            )
        self._joints = w.armature_joints.astype(np.int64)
        a0 = len(self._joints) + 1
        self._h_src = rest_height_m(src)
        self._h_tgt = rest_height_m(tgt)
        s_src = _static_features(w, src)
        s_tgt = _static_features(w, tgt)
        pools = [np.asarray(p) for p in w.pools]
        unpools = [(p > 0).astype(np.float64).T for p in pools]
        c0 = w.encoder[0][0].shape[0] // a0
        c1 = w.encoder[1][0].shape[0] // pools[0].shape[0]
        self._c0, self._c1 = c0, c1
        enc0 = _split_static(w.encoder[0], [_ROOT] + [4] * (a0 - 1), s_src[0])
        enc1 = _split_static(w.encoder[1], [c0] * pools[0].shape[0], s_src[1])
        dec0_k, dec0_b = _split_static(w.decoder[0], [c1] * pools[0].shape[0], s_tgt[1])
        dec1_k, dec1_b = _split_static(w.decoder[1], [c0] * a0, s_tgt[0])
        self._layers = [
            RingConv(enc0, 1),
            RingConv(enc1, 1),
            RingConv((_fold_unpool(dec0_k, unpools[1], c1), dec0_b), 1),
            RingConv((_fold_unpool(dec1_k, unpools[0], c0), dec1_b), 1),
        ]
        self._pools = [_f32(p) for p in pools]
        self._mean = w.root_mean
        self._std = w.root_std
        self._stream = FrameStream()
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._stream.reset()
        for layer in self._layers:
            layer.reset()

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q, root = check_frame(local_quats, root_pos)
        q = unit_quaternions(q)
        vel3, dyaw = self._stream.push(q, root)  # q is heading-free from here
        scaled = np.array([*(vel3 / self._h_src), dyaw])
        x = np.concatenate([q[0], (scaled - self._mean) / self._std, q[self._joints].reshape(-1)])
        enc0, enc1, dec0, dec1 = self._layers
        h = leaky_relu(enc0.step(_f32(x))).reshape(-1, self._c0)
        h = leaky_relu(enc1.step((self._pools[0] @ h).reshape(-1))).reshape(-1, self._c1)
        latent = (self._pools[1] @ h).reshape(-1)
        raw = dec1.step(leaky_relu(dec0.step(latent))).astype(np.float64)
        quats = np.empty((_J, 4))
        quats[0] = raw[:4]
        quats[self._joints] = raw[_ROOT:].reshape(-1, 4)
        # Unit rotations whatever the network produced (a zero output becomes the identity).
        norm = np.linalg.norm(quats, axis=-1, keepdims=True)
        quats = np.where(norm > 1e-12, quats / np.maximum(norm, 1e-6), _IDENTITY)
        vel = raw[4:_ROOT] * self._std + self._mean
        out_pos, out_yaw = self._stream.integrate(vel[:3] * self._h_tgt, float(vel[3]))
        return self._stream.apply_heading(quats, out_yaw), out_pos
