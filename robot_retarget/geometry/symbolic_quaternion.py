"""Quaternion and rotation arithmetic on CasADi SX scalars, for compiled per-frame steps.

A quaternion is a 4-tuple ``(w, x, y, z)`` of SX scalars, a vector a 3-tuple, a rotation matrix
a row-major 9-tuple. Scalars, not SX matrices: the graphs built here are flat lists of a few
thousand scalar operations that the C compiler turns into straight-line code
(:func:`robot_retarget.casadi_jit.compile_graph`), and Python tuples build them fastest. Each
function is the SX twin of its numpy counterpart in :mod:`robot_retarget.runtime.frame`, with
the same conventions (Hamilton product, w first, homogeneous matrix form of a unit quaternion).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca

Quat = Sequence[ca.SX]  # (w, x, y, z)
Vec = Sequence[ca.SX]  # (x, y, z)
Mat = Sequence[ca.SX]  # 3×3, row-major

# Below this angle sin(a/2)/a is replaced by its series 1/2 − a²/48 (exact in float64 there).
_SMALL_ANGLE = 1e-4
# A quaternion this short has no direction: unit_or_identity gives the identity.
_ZERO_QUAT_NORM = 1e-12


def qmul(a: Quat, b: Quat) -> Quat:
    """Hamilton product a ⊗ b."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def conj(q: Quat) -> Quat:
    return (q[0], -q[1], -q[2], -q[3])


def rotvec(q: Quat) -> Vec:
    """Rotation vector of a unit quaternion, shortest arc (as ``quaternion.to_rotation_vector``)."""
    w, x, y, z = q
    flip = ca.if_else(w < 0.0, -1.0, 1.0)
    vx, vy, vz = x * flip, y * flip, z * flip
    s = ca.sqrt(vx * vx + vy * vy + vz * vz)
    k = 2.0 * ca.atan2(s, ca.fabs(w)) / ca.fmax(s, 1e-300)
    return (k * vx, k * vy, k * vz)


def angle(q: Quat) -> ca.SX:
    """Rotation angle in [0, π] of a unit quaternion: 2·atan2(|v|, |w|)."""
    w, x, y, z = q
    return 2.0 * ca.atan2(ca.sqrt(x * x + y * y + z * z), ca.fabs(w))


IDENTITY: Mat = tuple(ca.SX(1.0 if i == j else 0.0) for i in range(3) for j in range(3))


def quat_at(v: ca.SX, i: int) -> Quat:
    """The ``i``-th quaternion of a flat SX vector of quaternions ((J, 4) row-major)."""
    return (v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3])


def vec_at(v: ca.SX, i: int) -> Vec:
    """The ``i``-th 3-vector of a flat SX vector of 3-vectors ((J, 3) row-major)."""
    return (v[3 * i], v[3 * i + 1], v[3 * i + 2])


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def scale(s: ca.SX, v: Vec) -> Vec:
    return (s * v[0], s * v[1], s * v[2])


def dot(a: Vec, b: Vec) -> ca.SX:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def norm(v: Vec) -> ca.SX:
    return ca.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit(v: Vec) -> tuple[Vec, ca.SX]:
    """``v / |v|`` and ``|v|`` (the caller guards a zero norm)."""
    n = norm(v)
    return (v[0] / n, v[1] / n, v[2] / n), n


def unit_or_zero(v: Vec) -> Vec:
    """``v / |v|``; a zero vector stays zero (as ``quaternion_torch.normalize``), never NaN."""
    inv = 1.0 / ca.fmax(norm(v), 1e-30)
    return (v[0] * inv, v[1] * inv, v[2] * inv)


def reject(v: Vec, u: Vec) -> Vec:
    """``v`` without its component along the unit vector ``u``."""
    d = dot(v, u)
    return (v[0] - d * u[0], v[1] - d * u[1], v[2] - d * u[2])


def transpose(m: Mat) -> Mat:
    return (m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8])


def from_rotvec(r: Vec) -> Quat:
    """Unit quaternion of a rotation vector (as ``quaternion.from_rotation_vector``), smooth
    at zero."""
    a = norm(r)
    half_sinc = ca.if_else(
        a < _SMALL_ANGLE, 0.5 - a * a / 48.0, ca.sin(0.5 * a) / ca.fmax(a, _SMALL_ANGLE)
    )
    return (ca.cos(0.5 * a), half_sinc * r[0], half_sinc * r[1], half_sinc * r[2])


def normalize(q: Quat) -> Quat:
    n = ca.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def unit_or_identity(q: Quat) -> Quat:
    """``q / |q|``, or the identity where |q| ≤ 1e-12 (as ``frame.unit_quaternions``)."""
    n = ca.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    ok = n > _ZERO_QUAT_NORM
    d = ca.fmax(n, _ZERO_QUAT_NORM)
    return tuple(ca.if_else(ok, c / d, ca.SX(1.0 if i == 0 else 0.0)) for i, c in enumerate(q))


def matrix(q: Quat) -> Mat:
    """Row-major rotation matrix of a unit quaternion, homogeneous form (as ``frame.matrices``)."""
    w, x, y, z = q
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    return (
        ww + xx - yy - zz,
        2.0 * (xy - wz),
        2.0 * (xz + wy),
        2.0 * (xy + wz),
        ww - xx + yy - zz,
        2.0 * (yz - wx),
        2.0 * (xz - wy),
        2.0 * (yz + wx),
        ww - xx - yy + zz,
    )


def matmul(a: Mat, b: Mat) -> Mat:
    return tuple(
        a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j]
        for i in range(3)
        for j in range(3)
    )


def rotate(m: Mat, v: Vec) -> Vec:
    return (
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    )


def qrotate(q: Quat, v: Vec) -> Vec:
    """``v`` turned by the unit quaternion ``q``."""
    return rotate(matrix(q), v)


def with_heading(q: Quat, yaw: ca.SX) -> Quat:
    """The rotation about +Y by ``yaw`` composed before ``q`` (as ``FrameStream.apply_heading``)."""
    fw, fx, fy, fz = q
    c, s = ca.cos(0.5 * yaw), ca.sin(0.5 * yaw)
    return (c * fw - s * fy, c * fx + s * fz, c * fy + s * fw, c * fz - s * fx)
