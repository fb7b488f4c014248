"""Euler angles in any of the 12 axis orders, to and from unit quaternions (numpy, batched).

Order strings: upper case is *intrinsic* (rotating axes), ``"ZYX"`` meaning
R = Rz(a0) · Ry(a1) · Rx(a2) — exactly how a BVH ``CHANNELS ... Zrotation Yrotation Xrotation``
line composes its values. Lower case is *extrinsic* (fixed axes), ``"xyz"`` meaning
R = Rz(a2) · Ry(a1) · Rx(a0). Both Tait–Bryan (three distinct axes) and proper Euler orders
(first axis = last axis, e.g. ``"ZXZ"``) are supported.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat

_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}
_GIMBAL_TOL = 1e-7


def parse_order(order: str) -> tuple[tuple[int, int, int], bool]:
    """Return (axis indices in order, intrinsic?) for an order string, validating it."""
    if len(order) != 3 or not (order.isupper() or order.islower()):
        raise ValueError(
            f"Euler order {order!r} must be three letters from X, Y, Z, all upper case "
            "(intrinsic) or all lower case (extrinsic)"
        )
    try:
        axes = tuple(_AXIS_INDEX[c] for c in order.lower())
    except KeyError:
        raise ValueError(f"Euler order {order!r} may only use the letters x, y, z") from None
    if axes[0] == axes[1] or axes[1] == axes[2]:
        raise ValueError(f"Euler order {order!r} repeats an axis in consecutive positions")
    return (axes[0], axes[1], axes[2]), order.isupper()


def _elementary(axis: int, angle: FloatArray) -> FloatArray:
    q = np.zeros((*angle.shape, 4))
    q[..., 0] = np.cos(0.5 * angle)
    q[..., 1 + axis] = np.sin(0.5 * angle)
    return q


def from_euler(angles_rad: npt.ArrayLike, order: str) -> FloatArray:
    """Unit quaternions (…, 4) from Euler angles (…, 3) in radians, in the given order."""
    axes, intrinsic = parse_order(order)
    angles = quat.as_float_array(angles_rad)
    if angles.shape[-1:] != (3,):
        raise ValueError(f"Euler angles need a last axis of length 3, got shape {angles.shape}")
    q0 = _elementary(axes[0], angles[..., 0])
    q1 = _elementary(axes[1], angles[..., 1])
    q2 = _elementary(axes[2], angles[..., 2])
    if intrinsic:
        return quat.mul(quat.mul(q0, q1), q2)
    return quat.mul(quat.mul(q2, q1), q0)


def to_euler(q: npt.ArrayLike, order: str) -> FloatArray:
    """Euler angles (…, 3) in radians of unit quaternions, in the given order.

    The first and last angles lie in (−π, π]; the middle one in [−π/2, π/2] for Tait–Bryan
    orders and [0, π] for proper Euler orders. At gimbal lock the last angle is set to zero.
    Uses the direct quaternion method of Bernardes & Viollet (2022).
    """
    axes, intrinsic = parse_order(order)
    q = quat.normalize(q)
    # Work on the extrinsic sequence; an intrinsic order is the reversed extrinsic one.
    i, j, k = (axes[2], axes[1], axes[0]) if intrinsic else axes
    proper = i == k
    if proper:
        k = 3 - i - j
    # Sign of the permutation (i, j, k) of (0, 1, 2).
    eps = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    w, qi, qj, qk = q[..., 0], q[..., 1 + i], q[..., 1 + j], q[..., 1 + k] * eps
    if proper:
        a, b, c, d = w, qi, qj, qk
    else:
        a, b, c, d = w - qj, qi + qk, qj + w, qk - qi
    theta2 = 2.0 * np.arctan2(np.hypot(c, d), np.hypot(a, b))
    half_sum = np.arctan2(b, a)
    half_diff = np.arctan2(d, c)
    at_zero = np.abs(theta2) < _GIMBAL_TOL
    at_pi = np.abs(theta2 - np.pi) < _GIMBAL_TOL
    # theta1 = θ+ − θ−, theta3 = θ+ + θ−. At a lock only their sum (θ2 = 0) or difference
    # (θ2 = π) is defined: put it all in one angle and set the other to 0 — the one that ends
    # up last in the caller's order (theta3 here, theta1 for intrinsic orders, which reverse).
    lock = at_zero | at_pi
    if intrinsic:
        theta1 = np.where(lock, 0.0, half_sum - half_diff)
        theta3 = np.where(
            at_zero, 2.0 * half_sum, np.where(at_pi, 2.0 * half_diff, half_sum + half_diff)
        )
    else:
        theta1 = np.where(
            at_zero, 2.0 * half_sum, np.where(at_pi, -2.0 * half_diff, half_sum - half_diff)
        )
        theta3 = np.where(lock, 0.0, half_sum + half_diff)
    if not proper:
        theta3 = eps * theta3
        theta2 = theta2 - 0.5 * np.pi
    out = np.stack([theta1, theta2, theta3], axis=-1)
    out = np.pi - np.mod(np.pi - out, 2.0 * np.pi)  # wrap to (−π, π]
    if intrinsic:
        out = out[..., ::-1]
    return np.ascontiguousarray(out)


def matrix_from_euler(angles_rad: npt.ArrayLike, order: str) -> FloatArray:
    """Rotation matrices (…, 3, 3) from Euler angles in radians."""
    return quat.to_matrix(from_euler(angles_rad, order))


def rpy_to_quat(rpy_rad: npt.ArrayLike) -> FloatArray:
    """URDF ``rpy`` (fixed-axis roll about x, pitch about y, yaw about z) to quaternions."""
    return from_euler(rpy_rad, "xyz")
