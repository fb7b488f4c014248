"""Canonical 3D joint positions → canonical local rotations (minimal twist).

Position streams (markerless trackers, other retargeters) send where the 22 canonical joints
are, not how they are rotated. Each joint's rotation is the *smallest* one that points its bone
(rest offset of its child) at the measured child: no twist is invented about the bone. Two
joints need a full frame rather than a direction: the Hips (spine up, hip line left) and Spine2
(neck up, shoulder line left); both use a triad whose first axis is met exactly. Leaves (Head,
hands, toes) keep the identity: positions cannot tell their roll.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction
from robot_retarget.errors import InvalidMotionError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    Joint,
    default_canonical_skeleton,
)
from robot_retarget.skeleton.position_solve_spec import (
    EPS,
    MIN_SECONDARY_M,
    PRIMARY_CHAIN,
    TRIAD_FALLBACK,
    TRIADS,
    single_children,
)
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.positions_graph import positions_function

_IDENTITY = np.eye(3)


def _frame(primary: FloatArray, secondary: FloatArray) -> FloatArray | None:
    """Orthonormal columns: primary exactly, secondary made orthogonal, then their cross."""
    n1 = math.sqrt(float(primary @ primary))
    if n1 < EPS:
        return None
    e1 = primary / n1
    s = secondary - e1 * float(e1 @ secondary)
    n2 = math.sqrt(float(s @ s))
    if n2 < EPS:
        return None
    e2 = s / n2
    (x1, y1, z1), (x2, y2, z2) = e1.tolist(), e2.tolist()
    e3 = np.array([y1 * z2 - z1 * y2, z1 * x2 - x1 * z2, x1 * y2 - y1 * x2])  # np.cross is slow
    return np.stack([e1, e2, e3], axis=1)


class PositionsToRotations:
    """Solves local rotations on ``skeleton`` (canonical joints; default the canonical
    skeleton's proportions) from global positions: what a pose estimator or tracker gives,
    ready for :class:`robot_retarget.pipeline.step.RetargetStep`."""

    def __init__(self, skeleton: Skeleton | None = None) -> None:
        if skeleton is None:
            skeleton = default_canonical_skeleton()
        if skeleton.names != CANONICAL_JOINTS:
            raise InvalidMotionError("PositionsToRotations needs a canonical 22-joint skeleton")
        self.skeleton = skeleton
        self._rest = skeleton.rest_positions()
        self._child = single_children(CANONICAL_PARENTS)
        self._rest_dirs: dict[int, FloatArray | None] = {}
        for j, c in self._child.items():
            d = skeleton.offsets[c]
            norm = float(np.linalg.norm(d))
            self._rest_dirs[j] = d / norm if norm > EPS else None
        self._rest_frames: dict[int, FloatArray | None] = {}
        self._triads: dict[int, tuple[int, tuple[int, int]]] = {}
        for j, (prim, (left, right)) in TRIADS.items():
            prim = next(
                (c for c in PRIMARY_CHAIN[j]
                 if np.linalg.norm(self._rest[c] - self._rest[j]) >= MIN_SECONDARY_M),
                prim,
            )  # fmt: skip
            side = self._rest[left] - self._rest[right]
            if np.linalg.norm(side) < MIN_SECONDARY_M and j in TRIAD_FALLBACK:
                left, right = TRIAD_FALLBACK[j]
                side = self._rest[left] - self._rest[right]
            self._triads[j] = (prim, (left, right))
            self._rest_frames[j] = _frame(self._rest[prim] - self._rest[j], side)
        # The same arithmetic as one casadi call (positions_graph); solve() takes the numpy
        # path below only where the graph's margin flags a degenerate frame.
        self._graph = CompiledFunction(
            positions_function(
                CANONICAL_PARENTS,
                self._child,
                self._rest_dirs,
                self._triads,
                self._rest_frames,
                EPS,
            )
        )
        self._p_in = self._graph.args[0].reshape(-1, 3)
        quats, self._margin = self._graph.res
        self._quats = quats.reshape(-1, 4)

    def solve(self, positions: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(22, 3) global positions (m, Y up) → local rotations (22, 4) and root position (3,)."""
        p = np.asarray(positions, dtype=np.float64)
        if p.shape != (len(CANONICAL_JOINTS), 3):
            raise InvalidMotionError(
                f"positions must have shape (22, 3), got {p.shape}: the canonical joints in the "
                "order of robot_retarget.skeleton.canonical.CANONICAL_JOINTS, metres, Y up"
            )
        if not np.isfinite(p).all():
            raise InvalidMotionError(
                "positions hold NaN or infinite values (a joint not seen: fill it or drop the "
                "frame)"
            )
        self._p_in[...] = p
        self._graph()
        if self._margin[0] > 0.0:
            return self._quats.copy(), p[Joint.Hips].copy()
        return self._numpy_solve(p)

    def _numpy_solve(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The solve in numpy, with the branches of degenerate frames."""
        n = len(CANONICAL_JOINTS)
        # 3×3 matrices in the loop (cheaper than quaternion helpers on single rows), one
        # batched conversion to quaternions at the end.
        glob = np.empty((n, 3, 3))
        local = np.empty((n, 3, 3))
        for j in range(n):
            parent = CANONICAL_PARENTS[j]
            g_parent = _IDENTITY if parent < 0 else glob[parent]
            if j in self._triads:
                prim, (left, right) = self._triads[j]
                cur = _frame(p[prim] - p[j], p[left] - p[right])
                rest = self._rest_frames[j]
                g = g_parent if cur is None or rest is None else cur @ rest.T
                glob[j] = g
                local[j] = g_parent.T @ g
                continue
            loc = _IDENTITY
            child = self._child.get(j)
            rest_dir = self._rest_dirs.get(j)
            if child is not None and rest_dir is not None:
                d_cur = g_parent.T @ (p[child] - p[j])
                norm = math.sqrt(float(d_cur @ d_cur))
                if norm > EPS:
                    loc = _shortest_arc(rest_dir, d_cur / norm)
            local[j] = loc
            glob[j] = g_parent @ loc
        return quat.normalize(quat.from_matrix(local)), p[Joint.Hips].copy()


def _shortest_arc(a: FloatArray, b: FloatArray) -> FloatArray:
    """Rotation matrix of the smallest rotation taking unit a onto unit b."""
    c = float(a @ b)
    if c < -1.0 + 1e-9:  # opposite: a half turn about any axis perpendicular to a
        return quat.to_matrix(quat.from_two_vectors(a, b))
    ax, ay, az = a.tolist()
    bx, by, bz = b.tolist()
    vx, vy, vz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx  # a × b
    k = np.array([[0.0, -vz, vy], [vz, 0.0, -vx], [-vy, vx, 0.0]])
    return _IDENTITY + k + (k @ k) / (1.0 + c)
