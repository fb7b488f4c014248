"""numpy building blocks of the live pipeline's per-frame network steps (no torch).

A network's online step works on one frame of a few hundred numbers, where torch spends nearly
all its time dispatching ops. The numpy twins of the models' steps (runtime.pmnet,
runtime.tdcn, runtime.copy, runtime.residual) share what this module holds:

- quaternion products and rotation matrices written as few array ops
  (tables from robot_retarget.geometry.quaternion_tables);
- :class:`TreeKinematics`: root-relative joint positions (and, for a batch, global rotations)
  by pointer jumping, as the torch ``FrameKinematics``;
- :class:`FrameStream`: the numpy ``FeatureStream`` — heading removal, heading-frame root
  velocity and turning rate of each source frame, integration of the predicted root
  velocity from the source's first position and heading, and the heading put back on the
  output root rotation.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import Float32Array, FloatArray
from robot_retarget.geometry.quaternion_tables import matrix_table, product_table
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS
from robot_retarget.skeleton.tree_tables import ancestor_matrix, pointer_jumps

F32Array = Float32Array

NUM_JOINTS = len(CANONICAL_JOINTS)
_TWO_PI = 2.0 * math.pi


_HAMILTON = product_table()


def qmul(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton product of same-shaped quaternion arrays (…, 4): one outer product, one matmul
    (per-call overhead is what costs at this size)."""
    outer = (a[..., :, None] * b[..., None, :]).reshape(*a.shape[:-1], 16)
    return np.asarray(outer @ _HAMILTON, dtype=np.float64)


_MATRIX = matrix_table()


def matrices(q: FloatArray) -> FloatArray:
    """Rotation matrices (J, 3, 3) of unit quaternions (J, 4)."""
    outer = (q[:, :, None] * q[:, None, :]).reshape(-1, 16)
    return np.asarray(outer @ _MATRIX, dtype=np.float64).reshape(-1, 3, 3)


class TreeKinematics:
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

    def pose(self, rot: FloatArray, offsets: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Global rotation matrices (T, J, 3, 3) and root-relative positions (T, J, 3) of
        frames of local rotation matrices (T, J, 3, 3), rest offsets (J, 3): :meth:`positions`
        for a batch, with the globals (kept apart: one frame's positions alone, on the live
        networks' hot path, are 1.3× faster unbatched)."""
        t, j = rot.shape[:2]
        glob = np.concatenate([rot, np.broadcast_to(np.eye(3), (t, 1, 3, 3))], axis=1)
        for anc in self._jumps:
            glob = glob[:, anc] @ glob
        bones = (glob[:, self._parent] @ offsets[..., None])[..., 0]
        return glob[:, :j], np.asarray(self._chain @ bones, dtype=np.float64)


def f32_layer(layer: tuple[FloatArray, FloatArray]) -> tuple[F32Array, F32Array]:
    """A (weight, bias) pair in float32: the torch models' precision, and matrix–vector
    products 2–4× faster than float64 (512-wide weights then fit the cache)."""
    return layer[0].astype(np.float32), layer[1].astype(np.float32)


def check_frame(
    local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """A frame as float64 copies, with OnlineRetargeter's shape errors."""
    q = np.array(local_quats, dtype=np.float64)
    root = np.array(root_pos, dtype=np.float64)
    if q.shape != (NUM_JOINTS, 4):
        raise ValueError(f"local_quats must have shape {(NUM_JOINTS, 4)}, got {q.shape}")
    if root.shape != (3,):
        raise ValueError(f"root_pos must have shape (3,), got {root.shape}")
    return q, root


def check_offsets(name: str, offsets: npt.ArrayLike) -> FloatArray:
    a = np.asarray(offsets, dtype=np.float64)
    if a.shape != (NUM_JOINTS, 3):
        raise ValueError(f"{name} must have shape {(NUM_JOINTS, 3)}, got {a.shape}")
    return a


class FrameStream:
    """The numpy ``FeatureStream`` (see the module docstring); :meth:`reset` before a new
    sequence."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._prev: tuple[float, float, float, float] | None = None  # source x, y, z, yaw
        self._out: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
        self._first = True

    def push(self, q: FloatArray, root: FloatArray) -> tuple[FloatArray, float]:
        """Remove the heading from ``q``'s root entry in place; returns the heading-frame root
        velocity (3,) and the turning rate (rad/frame), both zero on the first frame."""
        w, x, y, z = q[0].tolist()
        px, py, pz = root.tolist()
        # Heading of the root's +X column, as FeatureStream.
        yaw = math.atan2(-2.0 * (x * z - w * y), w * w + x * x - y * y - z * z)
        c, s = math.cos(-0.5 * yaw), math.sin(-0.5 * yaw)
        q[0] = (c * w - s * y, c * x + s * z, c * y + s * w, c * z - s * x)
        prev = self._prev
        self._prev = (px, py, pz, yaw)
        if prev is None:
            self._out = (px, py, pz, yaw)
            return np.zeros(3), 0.0
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy, dz = px - prev[0], py - prev[1], pz - prev[2]
        d = yaw - prev[3]
        return np.array((c * dx - s * dz, dy, s * dx + c * dz)), math.pi - (math.pi - d) % _TWO_PI

    def integrate(self, vel: FloatArray, dyaw: float) -> tuple[FloatArray, float]:
        """The target's root position (3,) and heading after one predicted velocity; the
        first frame's velocity is ignored (the output starts at the source's root)."""
        if self._first:
            self._first = False
        else:
            vx, vy, vz = vel.tolist()
            out_yaw = self._out[3] + dyaw
            c, s = math.cos(out_yaw), math.sin(out_yaw)
            self._out = (
                self._out[0] + (c * vx + s * vz),
                self._out[1] + vy,
                self._out[2] + (c * vz - s * vx),
                out_yaw,
            )
        return np.array(self._out[:3]), self._out[3]

    @staticmethod
    def apply_heading(q: FloatArray, yaw: float) -> FloatArray:
        """Put the heading ``yaw`` back on the root entry of heading-free rotations, in place."""
        fw, fx, fy, fz = q[0].tolist()
        c, s = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
        q[0] = (c * fw - s * fy, c * fx + s * fz, c * fy + s * fw, c * fz - s * fx)
        return q


_IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def unit_quaternions(q: FloatArray) -> FloatArray:
    """Unit quaternions (…, 4); a (near-)zero one becomes the identity, so whatever a
    sender or the network produces, the optimizer gets rotations."""
    n = np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    out: FloatArray = np.where(n > 1e-12, q / np.maximum(n, 1e-12), _IDENTITY)
    return out
