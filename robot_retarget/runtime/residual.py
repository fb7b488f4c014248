"""The residual model's online step without torch: compiled geometry and numpy dense layers.

:class:`robot_retarget.nn.models.residual.ResidualRetargeter` through torch costs ~0.5 ms per
frame, nearly all of it per-op dispatch on tensors of a few hundred numbers, and a numpy
transcription of it still made ~120 small calls (≈ 0.4 ms). :class:`FastResidualRetargeter`
runs the same arithmetic as ``RetargetModel.step`` in three compiled SX stages
(:mod:`robot_retarget.runtime.residual_graphs`: denoiser features, denoised pose and forward
kinematics, output rotations) between which the dense layers run as numpy matrix products with
their biases folded in (an appended constant 1), about twenty calls in all; heading removal,
root velocity and integration as ``FeatureStream`` (:class:`FrameStream`). Its output equals
:class:`robot_retarget.nn.inference.OnlineRetargeter`'s to float32 rounding (tested).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction
from robot_retarget.evaluation.skeleton_measures import leg_length
from robot_retarget.runtime.copy import rest_height_m
from robot_retarget.runtime.foot_lock_graph import STATE_SIZE
from robot_retarget.runtime.frame import (
    NUM_JOINTS,
    F32Array,
    FrameStream,
    check_frame,
    check_offsets,
)
from robot_retarget.runtime.residual_graphs import output_lock_function, residual_stages
from robot_retarget.runtime.residual_weights import ResidualWeights
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.foot_lock_spec import CONTACT_FPS
from robot_retarget.skeleton.skeleton import Skeleton

_J = NUM_JOINTS


def _affine(weight: FloatArray, bias: FloatArray, *, keep_one: bool) -> FloatArray:
    """``x ↦ W x + b`` as one matrix on ``[x; 1]``; ``keep_one`` adds the row that carries the
    constant 1 on to the next layer (ReLU leaves it 1)."""
    out, inp = weight.shape
    m = np.zeros((out + keep_one, inp + 1))
    m[:out, :inp] = weight
    m[:out, inp] = bias
    if keep_one:
        m[out, inp] = 1.0
    return m


class FastResidualRetargeter:
    """Online residual model: ``step`` (22, 4), (3,) → (22, 4), (3,)."""

    def __init__(
        self,
        weights: ResidualWeights,
        source_offsets: npt.ArrayLike,
        target_offsets: npt.ArrayLike,
        *,
        jit: bool = True,
        frame_rate_hz: float = CONTACT_FPS,
    ) -> None:
        src = check_offsets("source_offsets", source_offsets)
        tgt = check_offsets("target_offsets", target_offsets)
        w = weights
        k = w.denoiser_history
        self._stream = FrameStream()
        h_src, h_tgt = rest_height_m(src), rest_height_m(tgt)
        self._ratio = h_tgt / h_src
        features, pose, output = residual_stages(CANONICAL_PARENTS, k, jit=jit)
        # The stages share arrays: one's result is bound as the next one's argument.
        self._q = np.zeros((_J, 4))
        self._past = np.zeros((_J, k, 4))
        self._features = CompiledFunction(features, args=[self._q, self._past])
        feats, rel, self._past_next = self._features.res
        self._feats = feats.reshape(_J, -1)  # per joint: 4K + 1 features, then its one-hot code
        self._den_weights = np.zeros((_J, k))
        offsets = np.ascontiguousarray(src.reshape(-1))
        self._pose = CompiledFunction(
            pose, args=[self._q, rel, self._den_weights.reshape(-1), offsets]
        )
        q_den, pose_x = self._pose.res
        self._pose_x = pose_x
        self._u = np.zeros((_J, 3))
        self._yaw_cap = np.array([0.0, w.max_correction_rad])
        output_args = [q_den, self._u.reshape(-1), self._yaw_cap[:1], self._yaw_cap[1:]]
        # With the foot lock, the output stage and the lock are one compiled call.
        self._lock = _FootLockInputs(src, tgt, frame_rate_hz) if w.foot_lock else None
        if self._lock is None:
            self._output = CompiledFunction(output, args=output_args)
        else:
            self._output = CompiledFunction(
                output_lock_function(_J, jit=jit), args=output_args + self._lock.args
            )
        self._out = self._output.res[0].reshape(_J, 4)
        self._den_layers = _denoiser_layers(w, k)
        self._layers = _correction_layers(w, src, tgt, h_src, h_tgt)
        self._root_taps = w.root_taps
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._started = False
        self._vel_past = np.zeros((len(self._root_taps), 3))  # newest first
        self._stream.reset()
        if self._lock is not None:
            self._lock.reset()

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q_in, root = check_frame(local_quats, root_pos)
        q = self._q
        q[...] = q_in
        vel, dyaw = self._stream.push(q, root)  # q is heading-free from here
        if not self._started:
            self._past[...] = q[:, None]
            self._started = True
        self._features()
        self._past[...] = self._past_next.reshape(self._past.shape)
        x = self._feats.astype(np.float32)
        *hidden, last = self._den_layers
        for m in hidden:
            x = np.maximum(x @ m, 0.0)
        np.matmul(x, last, out=self._den_weights)
        self._pose()
        h = self._pose_x.astype(np.float32)
        *hidden32, last32 = self._layers
        for m32 in hidden32:
            h = np.maximum(m32 @ h, 0.0)
        np.matmul(last32, h, out=self._u.reshape(-1))
        window = self._vel_past
        window[1:] = window[:-1]
        window[0] = vel
        out_pos, self._yaw_cap[0] = self._stream.integrate(
            self._root_taps @ window * self._ratio, dyaw
        )
        if self._lock is not None:
            self._lock.write(q_in, root, out_pos)
        self._output()
        if self._lock is not None:
            self._lock.advance(self._output.res[1])
        return self._out.copy(), out_pos


class _FootLockInputs:
    """The foot lock's inputs and state (:mod:`robot_retarget.runtime.foot_lock_graph`), bound
    to the compiled output stage that applies it (``output_lock``)."""

    def __init__(self, src: FloatArray, tgt: FloatArray, rate_hz: float) -> None:
        if not rate_hz > 0.0:
            raise ValueError(f"frame_rate_hz must be positive, got {rate_hz}")
        leg = leg_length(Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, src))
        self._q_src = np.zeros(4 * _J)
        self._root_src = np.zeros(3)
        self._root_out = np.zeros(3)
        self._state = np.zeros(STATE_SIZE)
        self._first = np.ones(1)
        # In output_lock's order: the lock's inputs without q_out (the output itself).
        self.args = [
            self._q_src,
            self._root_src,
            np.ascontiguousarray(src.reshape(-1)),
            self._root_out,
            np.ascontiguousarray(tgt.reshape(-1)),
            np.array([leg]),
            np.array([float(rate_hz)]),
            self._state,
            self._first,
        ]

    def reset(self) -> None:
        self._first[0] = 1.0

    def write(self, q_src: FloatArray, root_src: FloatArray, root_out: FloatArray) -> None:
        """The performer's frame as it arrived and the output's root, before the call."""
        self._q_src[...] = q_src.reshape(-1)
        self._root_src[...] = root_src
        self._root_out[...] = root_out

    def advance(self, state_next: FloatArray) -> None:
        """After the call: the lock's state moves on to the one the call returned."""
        self._state[...] = state_next
        self._first[0] = 0.0


def _denoiser_layers(w: ResidualWeights, history: int) -> list[F32Array]:
    """The denoiser's layers as right-multiplied float32 matrices (as the torch model; 17 µs
    against 22 µs in float64 with one BLAS thread) on rows ``[features, one-hot]``: the first
    layer's bias joins the one-hot rows (they sum to 1) and a column carries a constant 1
    through the hidden layers for the next biases."""
    (d0, e0), *rest = w.denoiser_layers
    n_feat = 4 * history + 1
    first = np.zeros((d0.shape[1], d0.shape[0] + 1))
    first[:, :-1] = d0.T
    first[n_feat:, :-1] += e0
    first[n_feat:, -1] = 1.0
    layers = [first]
    for i, (wi, bi) in enumerate(rest):
        layers.append(_affine(wi, bi, keep_one=i < len(rest) - 1).T.copy())
    return [m.astype(np.float32) for m in layers]


def _correction_layers(
    w: ResidualWeights, src: FloatArray, tgt: FloatArray, h_src: float, h_tgt: float
) -> list[F32Array]:
    """The correction MLP as float32 matrices on ``[x; 1]`` (float32 as the torch model, and
    its matrix–vector products are 2–4× faster than float64)."""
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
        b0 + w0[:, pose_dim : pose_dim + k] @ ref_a + w0[:, pose_dim + k :] @ ref_b - w_pose @ mean
    )
    layers = [_affine(w_pose * scale, first_bias, keep_one=True)]
    layers += [_affine(wi, bi, keep_one=True) for wi, bi in w.correction_layers[1:]]
    layers.append(_affine(*w.to_delta, keep_one=False))
    return [m.astype(np.float32) for m in layers]
