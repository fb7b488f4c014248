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

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.geometry.quaternion_tables import matrix_table, product_table
from robot_retarget.nn.models.residual import ResidualRetargeter
from robot_retarget.pipeline.fast_copy import rest_height_m
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.tree_tables import ancestor_matrix, pointer_jumps

FloatArray = npt.NDArray[np.float64]

_J = len(CANONICAL_JOINTS)
_TWO_PI = 2.0 * math.pi
_REL_SCALE = 10.0  # as robot_retarget.nn.models.residual


_HAMILTON = product_table()


def _mul(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton product of same-shaped quaternion arrays (…, 4): one outer product, one matmul
    (per-call overhead is what costs at this size)."""
    outer = (a[..., :, None] * b[..., None, :]).reshape(*a.shape[:-1], 16)
    return np.asarray(outer @ _HAMILTON, dtype=np.float64)


def _left_matrices(q: FloatArray) -> FloatArray:
    """(…, 4, 4) matrices L(q) with q ⊗ p = L(q) p."""
    return np.asarray(q @ _LEFT, dtype=np.float64).reshape(*q.shape[:-1], 4, 4)


# H[i, k, o]: the coefficient of a_i b_k in output o, so L(a)[o, k] = Σ_i a_i H[i, k, o].
_LEFT = np.einsum("iko->iok", _HAMILTON.reshape(4, 4, 4)).reshape(4, 16)


_MATRIX = matrix_table()


def _matrices(q: FloatArray) -> FloatArray:
    """Rotation matrices (J, 3, 3) of unit quaternions (J, 4)."""
    outer = (q[:, :, None] * q[:, None, :]).reshape(-1, 16)
    return np.asarray(outer @ _MATRIX, dtype=np.float64).reshape(-1, 3, 3)


def _rotvec(q: FloatArray) -> FloatArray:
    """Rotation vectors (…, 3) of unit quaternions (…, 4), shortest arc.

    2·atan2(s, |w|)/s stays exact for tiny s (atan2 does not lose the ratio) and gives 0 at
    s = 0, so no series branch is needed (geometry.quaternion.to_rotation_vector agrees, tested).
    """
    w = q[..., :1]
    v = q[..., 1:] * np.where(w < 0.0, -1.0, 1.0)
    s = np.sqrt(np.sum(v * v, axis=-1, keepdims=True))
    return np.asarray(2.0 * np.arctan2(s, np.abs(w)) / np.maximum(s, 1e-300) * v)


def _from_rotvec(r: FloatArray) -> FloatArray:
    """Unit quaternions (…, 4) of rotation vectors (…, 3)."""
    angle = np.sqrt(np.sum(r * r, axis=-1, keepdims=True))
    # sin(a/2)/a = ½·sinc(a/2π): exact and smooth at zero.
    return np.concatenate([np.cos(0.5 * angle), 0.5 * np.sinc(angle / (2 * np.pi)) * r], axis=-1)


class _TreeKinematics:
    """Root-relative joint positions of one frame by pointer jumping (FrameKinematics' scheme)."""

    def __init__(self, parents: tuple[int, ...]) -> None:
        jumps = pointer_jumps(parents)
        self._jumps = [np.array(a) for a in jumps]
        self._parent = np.array(jumps[0][: len(parents)])
        self._chain = ancestor_matrix(parents)

    def positions(self, rot: FloatArray, offsets: FloatArray) -> FloatArray:
        """Positions (J, 3) from local rotation matrices (J, 3, 3) and rest offsets (J, 3)."""
        glob = np.concatenate([rot, np.eye(3)[None]], axis=0)
        for anc in self._jumps:
            glob = glob[anc] @ glob
        bones = np.einsum("jab,jb->ja", glob[self._parent], offsets)
        return np.asarray(self._chain @ bones, dtype=np.float64)


class FastResidualRetargeter:
    """Online residual model on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,)."""

    def __init__(
        self,
        model: ResidualRetargeter,
        source_offsets: npt.ArrayLike,
        target_offsets: npt.ArrayLike,
    ) -> None:
        src = np.asarray(source_offsets, dtype=np.float64)
        tgt = np.asarray(target_offsets, dtype=np.float64)
        for name, a in (("source_offsets", src), ("target_offsets", tgt)):
            if a.shape != (_J, 3):
                raise ValueError(f"{name} must have shape {(_J, 3)}, got {a.shape}")
        self._src = src
        self._kin = _TreeKinematics(CANONICAL_PARENTS)
        h_src, h_tgt = rest_height_m(src), rest_height_m(tgt)
        self._h_src = h_src
        self._ratio = h_tgt / h_src
        w = model.export_weights()
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
        # The skeletons' share of the first layer is fixed for this pair: fold it in.
        self._first_bias = (
            b0 + w0[:, pose_dim : pose_dim + k] @ ref_a + w0[:, pose_dim + k :] @ ref_b
        )
        # Input standardisation folded into the first layer: W (x − μ)/σ = (W/σ) x − (W/σ) μ.
        mean = np.concatenate([w.pose_mean, w.rot_mean])
        std = np.concatenate([w.pose_std, w.rot_std])
        scale = np.concatenate([np.full(3 * _J, 1.0 / h_src), np.ones(6 * _J)])
        w_pose = w0[:, :pose_dim] / std
        self._first_bias = self._first_bias - w_pose @ mean
        self._first_weight = w_pose * scale
        self._hidden = w.correction_layers[1:]
        self._to_delta = w.to_delta
        self._max_correction = w.max_correction_rad
        self._root_taps = w.root_taps
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._past: FloatArray | None = None
        self._vel_past = np.zeros((len(self._root_taps) - 1, 3))
        self._prev: tuple[float, float, float, float] | None = None  # x, y, z, yaw
        self._out: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def _denoise(self, q: FloatArray) -> FloatArray:
        if self._past is None:
            self._past = np.repeat(q[:, None], self._history, axis=1)
        conj = q * np.array([1.0, -1.0, -1.0, -1.0])
        # q_t⁻¹ ⊗ q_t−k for every k at once: one batched (K, 4) @ (4, 4) per joint.
        rel = _rotvec(self._past @ _left_matrices(conj).transpose(0, 2, 1))  # (J, K, 3)
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
        out = _mul(q, _from_rotvec(correction))
        out[0] = q[0]
        self._past = np.concatenate([q[:, None], self._past[:, :-1]], axis=1)
        return out

    def _delta(self, q: FloatArray) -> FloatArray:
        rot = _matrices(q)
        pos = self._kin.positions(rot, self._src)
        six = rot[:, :, :2].transpose(0, 2, 1)  # per joint: column 0, then column 1 (6D)
        x = np.concatenate([pos.reshape(-1), six.reshape(-1)])
        x = np.maximum(self._first_weight @ x + self._first_bias, 0.0)
        for w, b in self._hidden:
            x = np.maximum(w @ x + b, 0.0)
        w, b = self._to_delta
        cap = self._max_correction
        return _from_rotvec(cap * np.tanh((w @ x + b).reshape(_J, 3) / cap))

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q = np.array(local_quats, dtype=np.float64)
        root = np.asarray(root_pos, dtype=np.float64)
        if q.shape != (_J, 4):
            raise ValueError(f"local_quats must have shape {(_J, 4)}, got {q.shape}")
        if root.shape != (3,):
            raise ValueError(f"root_pos must have shape (3,), got {root.shape}")
        w, x, y, z = q[0].tolist()
        px, py, pz = root.tolist()
        yaw = math.atan2(-2.0 * (x * z - w * y), w * w + x * x - y * y - z * z)
        # Heading-free root rotation (yaw_mul(−yaw)), as FrameFeatures.local_quats.
        c, s = math.cos(-0.5 * yaw), math.sin(-0.5 * yaw)
        q[0] = (c * w - s * y, c * x + s * z, c * y + s * w, c * z - s * x)

        q_den = self._denoise(q)
        q_b = _mul(q_den, self._delta(q_den))
        q_b /= np.linalg.norm(q_b, axis=-1, keepdims=True)

        prev = self._prev
        self._prev = (px, py, pz, yaw)
        if prev is None:
            vel = np.zeros(3)
            dyaw = 0.0
        else:
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy, dz = px - prev[0], py - prev[1], pz - prev[2]
            vel = np.array((c * dx - s * dz, dy, s * dx + c * dz))
            d = yaw - prev[3]
            dyaw = math.pi - (math.pi - d) % _TWO_PI
        window = np.concatenate([vel[None], self._vel_past], axis=0)  # newest first
        self._vel_past = window[:-1]
        vx, vy, vz = (self._root_taps @ window * self._ratio).tolist()
        if prev is None:  # frame 0: the output starts at the source's root and heading
            self._out = (px, py, pz, yaw)
        else:
            out_yaw = self._out[3] + dyaw
            c, s = math.cos(out_yaw), math.sin(out_yaw)
            self._out = (
                self._out[0] + (c * vx + s * vz),
                self._out[1] + vy,
                self._out[2] + (c * vz - s * vx),
                out_yaw,
            )
        out_x, out_y, out_z, out_yaw = self._out
        fw, fx, fy, fz = q_b[0]
        c, s = math.cos(0.5 * out_yaw), math.sin(0.5 * out_yaw)
        q_b[0] = (c * fw - s * fy, c * fx + s * fz, c * fy + s * fw, c * fz - s * fx)
        return q_b, np.array((out_x, out_y, out_z))
