"""Batched unit quaternions in numpy, (w, x, y, z), Hamilton convention.

Every function takes arrays whose last axis is the quaternion (4) or vector (3) and broadcasts
over the leading axes. A quaternion q rotates a vector v as q ⊗ (0, v) ⊗ q*, which equals
``quat_to_matrix(q) @ v``. Composition ``quat_mul(a, b)`` applies b first, then a, like
``matrix(a) @ matrix(b)``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray

_EPS = 1e-12
# Below this |a × b| (with a · b < 0) the shortest-arc axis is rounding noise: see from_two_vectors.
_ANTIPARALLEL_CROSS = 1e-8


def as_float_array(x: npt.ArrayLike) -> FloatArray:
    """Return ``x`` as a float64 array (no copy when it already is one)."""
    return np.asarray(x, dtype=np.float64)


def _unit(v: npt.ArrayLike) -> FloatArray:
    va = as_float_array(v)
    n = np.linalg.norm(va, axis=-1, keepdims=True)
    if np.any(n < _EPS):
        raise ValueError("direction vectors must be non-zero")
    return va / n


def identity(shape: tuple[int, ...] = ()) -> FloatArray:
    """Identity quaternions of the given leading shape."""
    q = np.zeros((*shape, 4))
    q[..., 0] = 1.0
    return q


def mul(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Hamilton product a ⊗ b (rotation b first, then a)."""
    qa = as_float_array(a)
    qb = as_float_array(b)
    aw, ax, ay, az = qa[..., 0], qa[..., 1], qa[..., 2], qa[..., 3]
    bw, bx, by, bz = qb[..., 0], qb[..., 1], qb[..., 2], qb[..., 3]
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def conjugate(q: npt.ArrayLike) -> FloatArray:
    """Conjugate (the inverse of a unit quaternion)."""
    return as_float_array(q) * np.array([1.0, -1.0, -1.0, -1.0])


def normalize(q: npt.ArrayLike) -> FloatArray:
    """Scale to unit norm. Raises ValueError on (near-)zero quaternions."""
    qa = as_float_array(q)
    n = np.linalg.norm(qa, axis=-1, keepdims=True)
    if np.any(n < _EPS) or not np.all(np.isfinite(n)):
        raise ValueError("cannot normalise a zero or non-finite quaternion")
    return qa / n


def canonical_sign(q: npt.ArrayLike) -> FloatArray:
    """The representative with w ≥ 0 (q and -q are the same rotation)."""
    qa = as_float_array(q)
    return np.where(qa[..., :1] < 0.0, -qa, qa)


def make_continuous(q: npt.ArrayLike, axis: int = 0) -> FloatArray:
    """Flip signs along ``axis`` (time) so consecutive quaternions have a non-negative dot.

    Removes the q / -q jumps that break interpolation, filtering and network training.
    """
    qa = np.moveaxis(as_float_array(q).copy(), axis, 0)
    if qa.shape[0] > 1:
        dots = np.sum(qa[1:] * qa[:-1], axis=-1)
        # A flip at step t flips every later frame too: cumulative parity of the sign changes.
        flips = np.cumprod(np.where(dots < 0.0, -1.0, 1.0), axis=0)
        qa[1:] *= flips[..., None]
    return np.moveaxis(qa, 0, axis)


def rotate(q: npt.ArrayLike, v: npt.ArrayLike) -> FloatArray:
    """Rotate vectors v (…, 3) by unit quaternions q (…, 4)."""
    qa = as_float_array(q)
    va = as_float_array(v)
    w = qa[..., :1]
    u = qa[..., 1:]
    t = 2.0 * cross(u, va)
    return va + w * t + cross(u, t)


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product over the last axis; several times faster than np.cross on small arrays,
    which dominates per-frame forward kinematics."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def to_matrix(q: npt.ArrayLike) -> FloatArray:
    """Rotation matrices (…, 3, 3) of unit quaternions (…, 4)."""
    qa = as_float_array(q)
    w, x, y, z = qa[..., 0], qa[..., 1], qa[..., 2], qa[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.stack(
        [
            1 - 2 * (yy + zz),
            2 * (xy - wz),
            2 * (xz + wy),
            2 * (xy + wz),
            1 - 2 * (xx + zz),
            2 * (yz - wx),
            2 * (xz - wy),
            2 * (yz + wx),
            1 - 2 * (xx + yy),
        ],
        axis=-1,
    )
    return m.reshape((*qa.shape[:-1], 3, 3))


def from_matrix(matrix: npt.ArrayLike) -> FloatArray:
    """Unit quaternions (w ≥ 0) of rotation matrices (…, 3, 3), numerically robust everywhere."""
    m = as_float_array(matrix)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    # Four candidate formulas; pick per element the one with the largest pivot (Shepperd).
    cands = np.stack(
        [
            np.stack(
                [
                    1 + m00 + m11 + m22,
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    1 + m00 - m11 - m22,
                    m[..., 0, 1] + m[..., 1, 0],
                    m[..., 0, 2] + m[..., 2, 0],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 0, 1] + m[..., 1, 0],
                    1 - m00 + m11 - m22,
                    m[..., 1, 2] + m[..., 2, 1],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[..., 1, 0] - m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 1, 2] + m[..., 2, 1],
                    1 - m00 - m11 + m22,
                ],
                axis=-1,
            ),
        ],
        axis=-2,
    )
    pivots = np.stack(
        [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22],
        axis=-1,
    )
    best = np.argmax(pivots, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    return canonical_sign(normalize(q))


def from_axis_angle(axis: npt.ArrayLike, angle_rad: npt.ArrayLike) -> FloatArray:
    """Quaternions rotating by ``angle_rad`` about ``axis`` (normalised here; need not be unit)."""
    ax = as_float_array(axis)
    angle = as_float_array(angle_rad)
    n = np.linalg.norm(ax, axis=-1, keepdims=True)
    if np.any(n < _EPS):
        raise ValueError("rotation axis must be non-zero")
    half = 0.5 * angle[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * ax / n], axis=-1)


def from_rotation_vector(rotvec: npt.ArrayLike) -> FloatArray:
    """Quaternions from rotation vectors (axis · angle), exact near zero."""
    rv = as_float_array(rotvec)
    angle = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle → 1/2 − angle²/48 near zero.
    small = angle < 1e-6
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half), scale * rv], axis=-1)


def to_axis_angle(q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """(unit axis (…, 3), angle in [0, π]) of unit quaternions; axis is x̂ for zero rotation."""
    q = canonical_sign(q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    safe = s > _EPS
    axis = np.where(safe[..., None], v / np.where(safe, s, 1.0)[..., None], [1.0, 0.0, 0.0])
    return axis, angle


def to_rotation_vector(q: npt.ArrayLike) -> FloatArray:
    """Rotation vectors (axis · angle, angle in [0, π]) of unit quaternions, exact near zero."""
    qc = canonical_sign(q)
    w = qc[..., :1]
    v = qc[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    # 2·atan2(s, w)/s → (2/w)(1 − s²/3w²) near zero: keeps the direction of tiny rotations,
    # which going through to_axis_angle (x̂ below |v| = 1e-12) loses.
    small = s < 1e-6
    safe_s = np.where(small, 1.0, s)
    safe_w = np.where(small & (w > 0.0), w, 1.0)
    factor = np.where(
        small, (2.0 / safe_w) * (1.0 - s**2 / (3.0 * safe_w**2)), 2.0 * np.arctan2(s, w) / safe_s
    )
    return factor * v


def angle_between(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Rotation angle (rad, in [0, π]) of a* ⊗ b: the geodesic distance between rotations."""
    rel = mul(conjugate(a), b)
    # atan2 keeps full precision for tiny angles, where arccos of the dot product does not.
    return 2.0 * np.arctan2(np.linalg.norm(rel[..., 1:], axis=-1), np.abs(rel[..., 0]))


def slerp(a: npt.ArrayLike, b: npt.ArrayLike, t: npt.ArrayLike) -> FloatArray:
    """Spherical linear interpolation from a (t = 0) to b (t = 1) along the shorter arc."""
    qa = as_float_array(a)
    qb = as_float_array(b)
    tt = as_float_array(t)[..., None]
    d = np.sum(qa * qb, axis=-1, keepdims=True)
    qb = np.where(d < 0.0, -qb, qb)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-9
    safe_sin = np.where(near, 1.0, sin_theta)
    wa = np.where(near, 1.0 - tt, np.sin((1.0 - tt) * theta) / safe_sin)
    wb = np.where(near, tt, np.sin(tt * theta) / safe_sin)
    return normalize(wa * qa + wb * qb)


def swing_twist(q: npt.ArrayLike, axis: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Split q into swing ⊗ twist, twist a rotation about ``axis`` (in q's local frame).

    ``mul(swing, twist)`` reproduces q; swing has no component about ``axis``. When q is a
    half-turn perpendicular to the axis the twist is undefined; identity is returned then.
    """
    qa = as_float_array(q)
    u = _unit(axis)
    proj = np.sum(qa[..., 1:] * u, axis=-1, keepdims=True)
    twist = np.concatenate([qa[..., :1], proj * u * np.ones_like(qa[..., 1:])], axis=-1)
    n = np.linalg.norm(twist, axis=-1, keepdims=True)
    degenerate = n < 1e-12
    twist = np.where(degenerate, identity(()), twist / np.where(degenerate, 1.0, n))
    swing = mul(qa, conjugate(twist))
    return swing, twist


def twist_angle(q: npt.ArrayLike, axis: npt.ArrayLike) -> FloatArray:
    """Signed twist angle (rad, in (−π, π]) of q about ``axis`` (right-hand rule)."""
    qa = as_float_array(q)
    proj = np.sum(qa[..., 1:] * _unit(axis), axis=-1)
    angle = 2.0 * np.arctan2(proj, qa[..., 0])
    # Wrap to (−π, π]: q and −q give angles differing by 2π.
    return np.asarray(np.pi - np.mod(np.pi - angle, 2.0 * np.pi), dtype=np.float64)


def from_two_vectors(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Shortest-arc rotation taking direction a onto direction b.

    Axis a × b, angle atan2(|a × b|, a · b). Near antiparallel directions the shortest arc's
    axis is ill-conditioned (a × b is then mostly rounding, direction error ≈ 1e-16 / |a × b|):
    below |a × b| = 1e-8 with a · b < 0 a fixed axis perpendicular to a is used instead, which
    keeps the image of a within ≈ 2e-8 of b everywhere.
    """
    ua = _unit(a)
    ub = _unit(b)
    c = cross(ua, ub)
    s = np.linalg.norm(c, axis=-1, keepdims=True)
    d = np.sum(ua * ub, axis=-1, keepdims=True)
    half = 0.5 * np.arctan2(s, d)
    # Parallel (any axis: the angle is ~0) or nearly opposite (a × b is rounding noise).
    helper = np.where(np.abs(ua[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    perp = cross(ua, helper)
    perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
    degenerate = (s < 1e-200) | ((s < _ANTIPARALLEL_CROSS) & (d < 0.0))
    axis = np.where(degenerate, perp, c / np.where(degenerate, 1.0, s))
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)
