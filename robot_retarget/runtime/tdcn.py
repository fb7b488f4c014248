"""numpy twin of TDCN (robot_retarget.nn.models.tdcn): whole clips and a causal online step.

:func:`run_clip` runs the convolution stack over a whole clip (causal or centred, as the
model was trained). :class:`FastTDCNRetargeter` is the live path's step for a causal TDCN:
every temporal layer keeps a ring of its last (k − 1)·d + 1 inputs (d its dilation), so a frame
costs one matrix–vector product per layer, whatever the receptive field (81 frames for the
published net); the ring starts filled with the first frame, as the clip path's left padding.
Batch norm is folded into the convolutions at export; the products run in float32, as the
torch model does. Both equal the torch model to float32 rounding (tests/runtime).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction
from robot_retarget.runtime.copy import rest_height_m
from robot_retarget.runtime.frame import (
    F32Array,
    FrameStream,
    TreeKinematics,
    check_frame,
    check_offsets,
    matrices,
    qmul,
    unit_quaternions,
)
from robot_retarget.runtime.ring_conv import Conv, RingConv, f32_conv, leaky_relu
from robot_retarget.runtime.tdcn_graphs import tdcn_stages
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS

_J = len(CANONICAL_JOINTS)


@dataclass(frozen=True)
class TDCNWeights:
    """A TDCN's parameters (batch norm folded into the kernels) and input statistics.

    ``flags`` = (causal, residual_rotations) as 0/1.
    """

    dilations: tuple[float, ...]
    flags: tuple[float, float]
    pose_mean: FloatArray
    pose_std: FloatArray
    quat_mean: FloatArray
    quat_std: FloatArray
    vel_mean: FloatArray
    vel_std: FloatArray
    offset_mean: FloatArray
    offset_std: FloatArray
    expand: Conv
    dilated: tuple[Conv, ...]
    pointwise: tuple[Conv, ...]
    features: Conv
    head: Conv

    @property
    def causal(self) -> bool:
        return bool(float(self.flags[0]))

    @property
    def residual_rotations(self) -> bool:
        return bool(float(self.flags[1]))

    @property
    def receptive_field(self) -> int:
        k = self.expand[0].shape[-1]
        return 1 + (k - 1) * int(sum(float(d) for d in self.dilations))


def _canonical(q: FloatArray) -> FloatArray:
    return np.where(q[..., :1] < 0.0, -q, q)


class _Head:
    """Input standardisation and the output transform shared by the clip and step paths."""

    def __init__(self, w: TDCNWeights, src: FloatArray, tgt: FloatArray) -> None:
        self.w = w
        self.h_src = rest_height_m(src)
        self.h_tgt = rest_height_m(tgt)
        self.tgt_in = (tgt.reshape(-1) - w.offset_mean) / w.offset_std

    def inputs(self, pose: FloatArray, quats: FloatArray, vel: FloatArray) -> FloatArray:
        """(…, J, 3), (…, J, 4), (…, 4) → standardised [p, q, v, s̄_B] (…, in_dim)."""
        w = self.w
        lead = pose.shape[:-2]
        return np.concatenate(
            [
                (pose.reshape(*lead, -1) - w.pose_mean) / w.pose_std,
                (_canonical(quats).reshape(*lead, -1) - w.quat_mean) / w.quat_std,
                (vel - w.vel_mean) / w.vel_std,
                np.broadcast_to(self.tgt_in, (*lead, self.tgt_in.shape[0])),
            ],
            axis=-1,
        )

    def outputs(
        self, raw: FloatArray, quats: FloatArray, vel: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Head output (…, 4J + 4) → rotations (…, J, 4) and root movement (…, 4)."""
        raw_q = unit_quaternions(raw[..., : 4 * _J].reshape(*raw.shape[:-1], _J, 4))
        q_b = unit_quaternions(qmul(quats, raw_q)) if self.w.residual_rotations else raw_q
        dv = raw[..., 4 * _J :]
        move = (vel[..., :3] / self.h_src + dv[..., :3]) * self.h_tgt
        return q_b, np.concatenate([move, vel[..., 3:] + dv[..., 3:]], axis=-1)


def _conv_clip(
    x: npt.NDArray[np.floating], conv: tuple[F32Array, F32Array], dilation: int, causal: bool
) -> npt.NDArray[np.floating]:
    """Padded convolution of (C, T) as the torch layers (first / last frame repeated)."""
    kern, bias = conv
    k = kern.shape[-1]
    span = (k - 1) * dilation
    left, right = (span, 0) if causal else (span // 2, span - span // 2)
    t = x.shape[1]
    xp = np.concatenate([np.repeat(x[:, :1], left, 1), x, np.repeat(x[:, -1:], right, 1)], 1)
    acc = np.repeat(bias[:, None], t, axis=1)
    for i in range(k):
        acc = acc + kern[:, :, i] @ xp[:, i * dilation : i * dilation + t]
    out: npt.NDArray[np.floating] = acc
    return out


def _features_of_clip(
    local_quats: FloatArray, root_pos: FloatArray, src: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Heading-free poses (T, J, 3), rotations (T, J, 4) and root movement (T, 4) of a clip,
    through the same per-frame stream as the live path."""
    stream = FrameStream()
    kin = TreeKinematics(CANONICAL_PARENTS)
    poses, quats, vels = [], [], []
    for q_in, r in zip(local_quats, root_pos, strict=True):
        q, root = check_frame(q_in, r)
        vel, dyaw = stream.push(q, root)
        poses.append(kin.positions(matrices(q), src))
        quats.append(q)
        vels.append(np.concatenate([vel, [dyaw]]))
    return np.stack(poses), np.stack(quats), np.stack(vels)


def run_clip(
    weights: TDCNWeights,
    local_quats: npt.ArrayLike,
    root_pos: npt.ArrayLike,
    source_offsets: npt.ArrayLike,
    target_offsets: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """A whole clip (T, 22, 4), (T, 3) → target rotations (T, 22, 4) and root (T, 3), causal or
    centred as the model was trained (``convert`` of a non-causal TDCN)."""
    src = check_offsets("source_offsets", source_offsets)
    tgt = check_offsets("target_offsets", target_offsets)
    q_in = np.asarray(local_quats, dtype=np.float64)
    r_in = np.asarray(root_pos, dtype=np.float64)
    pose, quats, vel = _features_of_clip(q_in, r_in, src)
    w = weights
    head = _Head(w, src, tgt)
    causal = w.causal
    x = head.inputs(pose, quats, vel).T.astype(np.float32)
    h = leaky_relu(_conv_clip(x, f32_conv(w.expand), 1, causal))
    for d, dil, point in zip(w.dilations[1:], w.dilated, w.pointwise, strict=True):
        inner = leaky_relu(_conv_clip(h, f32_conv(dil), int(float(d)), causal))
        h = h + leaky_relu(_conv_clip(inner, f32_conv(point), 1, causal))
    f = leaky_relu(_conv_clip(h, f32_conv(w.features), 1, causal))
    raw = _conv_clip(f, f32_conv(w.head), 1, causal).T.astype(np.float64)
    q_b, v_b = head.outputs(raw, quats, vel)
    stream = FrameStream()
    out_q = np.empty_like(q_b)
    out_r = np.empty((len(q_b), 3))
    for t in range(len(q_b)):
        stream.push(q_in[t].copy(), r_in[t])
        out_r[t], yaw = stream.integrate(v_b[t, :3], float(v_b[t, 3]))
        out_q[t] = stream.apply_heading(q_b[t].copy(), yaw)
    return out_q, out_r


class FastTDCNRetargeter:
    """Online causal TDCN on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,)."""

    def __init__(
        self,
        weights: TDCNWeights,
        source_offsets: npt.ArrayLike,
        target_offsets: npt.ArrayLike,
        *,
        jit: bool = True,
    ) -> None:
        src = check_offsets("source_offsets", source_offsets)
        tgt = check_offsets("target_offsets", target_offsets)
        w = weights
        if not w.causal:
            raise ValueError(
                "this TDCN is non-causal (it needs future frames) and has no online step; "
                "stream a causal TDCN (train --model tdcn --model-config causal=true)"
            )
        self._head = _Head(w, src, tgt)
        self._stream = FrameStream()
        # The geometry around the convolutions as two compiled calls (tdcn_graphs); their
        # constant inputs (offsets, statistics, heights) are bound once.
        inputs, outputs = tdcn_stages(CANONICAL_PARENTS, w.residual_rotations, jit=jit)
        self._q = np.zeros((_J, 4))
        self._vel = np.zeros(4)
        self._inputs = CompiledFunction(
            inputs,
            args=[
                self._q,
                self._vel,
                np.ascontiguousarray(src.reshape(-1)),
                np.concatenate([w.pose_mean, w.quat_mean, w.vel_mean]),
                np.concatenate([w.pose_std, w.quat_std, w.vel_std]),
            ],
        )
        self._x, q_unit = self._inputs.res
        self._raw = np.zeros(4 * _J + 4)
        self._outputs = CompiledFunction(
            outputs,
            args=[self._raw, q_unit, self._vel, np.array([self._head.h_src, self._head.h_tgt])],
        )
        q_b, self._move = self._outputs.res
        self._q_b = q_b.reshape(_J, 4)
        # The target's offsets are the same every frame: fold their share of the first
        # convolution (all taps, since the padding repeats them too) into its bias.
        kern, bias = w.expand
        n_tgt = self._head.tgt_in.shape[0]
        fixed = kern[:, -n_tgt:, :].sum(-1) @ self._head.tgt_in
        self._expand = RingConv((kern[:, :-n_tgt, :], bias + fixed), 1)
        self._dilated = [
            RingConv(c, int(float(d))) for c, d in zip(w.dilated, w.dilations[1:], strict=True)
        ]
        self._pointwise = [RingConv(c, 1) for c in w.pointwise]
        self._features = RingConv(w.features, 1)
        self._out = RingConv(w.head, 1)
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._stream.reset()
        for layer in (self._expand, *self._dilated):
            layer.reset()

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q, root = check_frame(local_quats, root_pos)
        # Scaled quaternions from a sender are still rotations: make them unit (the torch
        # model assumes unit input; for unit input this changes nothing beyond rounding). The
        # root first, here, as the heading is read from it; the rest in the inputs stage.
        q[0] = unit_quaternions(q[0])
        vel3, dyaw = self._stream.push(q, root)  # q is heading-free from here
        self._q[...] = q
        self._vel[:3] = vel3
        self._vel[3] = dyaw
        self._inputs()
        h = leaky_relu(self._expand.step(self._x.astype(np.float32)))
        for dil, point in zip(self._dilated, self._pointwise, strict=True):
            h = h + leaky_relu(point.step(leaky_relu(dil.step(h))))
        np.copyto(self._raw, self._out.step(leaky_relu(self._features.step(h))))
        self._outputs()
        out_pos, out_yaw = self._stream.integrate(self._move[:3], float(self._move[3]))
        return self._stream.apply_heading(self._q_b.copy(), out_yaw), out_pos
