"""Quaternion products and rotation matrices as constant tables (numpy).

Per-frame code on a few hundred numbers is dominated by per-call overhead, so the Hamilton
product and the rotation matrix of many quaternions are written as one outer product and one
matrix product with a constant table. The tables are read off :mod:`robot_retarget.geometry.
quaternion` itself (no hand-written signs); the torch FK layer, PMnet, the optimizer's targets
and the live numpy steps all use these.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat


@lru_cache(maxsize=1)
def _product() -> FloatArray:
    basis = np.eye(4)
    table = np.array([quat.mul(basis[a], basis[b]) for a in range(4) for b in range(4)])
    table.setflags(write=False)
    return table


def product_table() -> FloatArray:
    """(16, 4) H with a ⊗ b = (a bᵀ).flatten() @ H (the Hamilton product), read-only."""
    return _product()


@lru_cache(maxsize=1)
def _rotation() -> FloatArray:
    basis = np.eye(4)

    def form(q: FloatArray) -> FloatArray:  # the quadratic part of rotate(q, ·), row-major 3×3
        return np.asarray((quat.rotate(q[None], np.eye(3)) - np.eye(3)).T.ravel())

    table = np.zeros((4, 4, 9))
    for a in range(4):
        table[a, a] = form(basis[a])
        for b in range(a + 1, 4):
            # Polarisation: the form of e_a + e_b minus the squares is the cross term.
            table[a, b] = table[b, a] = 0.5 * (
                form(basis[a] + basis[b]) - form(basis[a]) - form(basis[b])
            )
    out = table.reshape(16, 9)
    out.setflags(write=False)
    return out


def rotation_table() -> FloatArray:
    """(16, 9) T with quat.rotate(q, ·) = (q qᵀ).flatten() @ T + I as a row-major 3×3 matrix,
    for any q (unit or not): rotate is v + w·t + u × t, quadratic in q."""
    return _rotation()


@lru_cache(maxsize=1)
def _matrix() -> FloatArray:
    table = _rotation().reshape(4, 4, 9).copy()
    # For unit q, I = (w² + x² + y² + z²)·I: the identity joins the quadratic form.
    for a in range(4):
        table[a, a, [0, 4, 8]] += 1.0
    out = table.reshape(16, 9)
    out.setflags(write=False)
    return out


def matrix_table() -> FloatArray:
    """(16, 9) T with R(q).flatten() = (q qᵀ).flatten() @ T for *unit* q (homogeneous form)."""
    return _matrix()
