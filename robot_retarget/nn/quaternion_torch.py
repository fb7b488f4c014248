"""Batched, differentiable unit quaternions in torch, (w, x, y, z), Hamilton convention.

Mirrors :mod:`robot_retarget.geometry.quaternion` and :mod:`robot_retarget.geometry.euler`
name for name, with the same conventions, so data preparation in numpy and losses in torch
agree to rounding: ``mul(a, b)`` applies b first, then a; ``rotate(q, v) == to_matrix(q) @ v``;
Euler order strings are upper case intrinsic, lower case extrinsic.

Differences from the numpy functions, all for use inside training loops:

- Nothing raises on data *values* (checking would force a device sync every call). Zero
  quaternions, zero axes and zero vectors give finite outputs and finite gradients instead
  (``normalize`` of zero returns zero). Wrong shapes and bad order strings still raise
  ValueError, as in numpy.
- Where a function is not differentiable (a norm at zero, Euler angles at gimbal lock), a safe
  branch keeps the gradient finite, so one degenerate sample never turns a batch into NaN.

Every function broadcasts over leading dimensions, works for float32 and float64 on any device
and returns tensors of its inputs' dtype and device.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from robot_retarget.geometry.euler import parse_order

Tensor = torch.Tensor

# Same thresholds as the numpy module, so both take the same branch on the same input.
_EPS = 1e-12
_GIMBAL_TOL = 1e-7
# Floor under squared norms before a square root: keeps d|v|/dv finite at v = 0 while changing
# no norm above 1e-15 (representable in float32 too).
_TINY_SQ = 1e-30


def _norm(v: Tensor, keepdim: bool = False) -> Tensor:
    """Euclidean norm over the last axis with a finite gradient at zero."""
    return torch.sqrt(torch.clamp_min(torch.sum(v * v, dim=-1, keepdim=keepdim), _TINY_SQ))


def _unit(v: Tensor) -> Tensor:
    """Unit vectors; a zero vector stays zero (numpy raises instead)."""
    return normalize(v)


def _cat_wv(w: Tensor, v: Tensor) -> Tensor:
    """Concatenate scalar parts (…, 1) and vector parts (…, 3), broadcasting the leading dims."""
    lead = np.broadcast_shapes(w.shape[:-1], v.shape[:-1])
    return torch.cat([w.expand(*lead, 1), v.expand(*lead, 3)], dim=-1)


def _cross(a: Tensor, b: Tensor) -> Tensor:
    """Cross product over the last axis, broadcasting the leading dims."""
    shape = np.broadcast_shapes(a.shape, b.shape)
    return torch.linalg.cross(a.expand(shape), b.expand(shape), dim=-1)


def _as_like(x: Tensor | float, like: Tensor) -> Tensor:
    return torch.as_tensor(x, dtype=like.dtype, device=like.device)


def _safe_atan2(y: Tensor, x: Tensor) -> Tensor:
    """atan2 whose gradient is zero (not NaN) at y = x = 0, where the angle is undefined."""
    both_zero = (x == 0.0) & (y == 0.0)
    return torch.atan2(y, torch.where(both_zero, torch.ones_like(x), x))


def identity(
    shape: tuple[int, ...] = (),
    *,
    dtype: torch.dtype | None = None,
    device: torch.device | str | None = None,
) -> Tensor:
    """Identity quaternions of the given leading shape."""
    q = torch.zeros((*shape, 4), dtype=dtype, device=device)
    q[..., 0] = 1.0
    return q


def mul(a: Tensor, b: Tensor) -> Tensor:
    """Hamilton product a ⊗ b (rotation b first, then a)."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        dim=-1,
    )


def conjugate(q: Tensor) -> Tensor:
    """Conjugate (the inverse of a unit quaternion)."""
    return torch.cat([q[..., :1], -q[..., 1:]], dim=-1)


def normalize(q: Tensor, eps: float = _EPS) -> Tensor:
    """Scale to unit norm along the last axis (works for vectors too).

    Norms below ``eps`` are treated as ``eps``: a zero input returns zero with a finite gradient
    instead of NaN. Above ``eps`` the result equals ``q / |q|`` exactly.
    """
    n2 = torch.sum(q * q, dim=-1, keepdim=True)
    return q / torch.sqrt(torch.clamp_min(n2, eps * eps))


def canonical_sign(q: Tensor) -> Tensor:
    """The representative with w ≥ 0 (q and -q are the same rotation)."""
    return torch.where(q[..., :1] < 0.0, -q, q)


def make_continuous(q: Tensor, axis: int = 0) -> Tensor:
    """Flip signs along ``axis`` (time) so consecutive quaternions have a non-negative dot."""
    qa = q.movedim(axis, 0)
    if qa.shape[0] <= 1:
        return q
    dots = torch.sum(qa[1:] * qa[:-1], dim=-1)
    step = torch.where(dots < 0.0, -torch.ones_like(dots), torch.ones_like(dots))
    # A flip at step t flips every later frame too: cumulative parity of the sign changes.
    flips = torch.cumprod(step, dim=0)
    out = torch.cat([qa[:1], qa[1:] * flips[..., None]], dim=0)
    return out.movedim(0, axis)


def rotate(q: Tensor, v: Tensor) -> Tensor:
    """Rotate vectors v (…, 3) by unit quaternions q (…, 4)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def to_matrix(q: Tensor) -> Tensor:
    """Rotation matrices (…, 3, 3) of unit quaternions (…, 4)."""
    w, x, y, z = q.unbind(-1)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = torch.stack(
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
        dim=-1,
    )
    return m.reshape(*q.shape[:-1], 3, 3)


def from_matrix(matrix: Tensor) -> Tensor:
    """Unit quaternions (w ≥ 0) of rotation matrices (…, 3, 3), robust everywhere (Shepperd)."""
    m = matrix
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    m01, m02, m10 = m[..., 0, 1], m[..., 0, 2], m[..., 1, 0]
    m12, m20, m21 = m[..., 1, 2], m[..., 2, 0], m[..., 2, 1]
    pivots = torch.stack(
        [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22],
        dim=-1,
    )
    cands = torch.stack(
        [
            torch.stack([pivots[..., 0], m21 - m12, m02 - m20, m10 - m01], dim=-1),
            torch.stack([m21 - m12, pivots[..., 1], m01 + m10, m02 + m20], dim=-1),
            torch.stack([m02 - m20, m01 + m10, pivots[..., 2], m12 + m21], dim=-1),
            torch.stack([m10 - m01, m02 + m20, m12 + m21, pivots[..., 3]], dim=-1),
        ],
        dim=-2,
    )
    # The candidate with the largest pivot has norm ≥ 1: well conditioned, gradient finite.
    best = torch.argmax(pivots, dim=-1)
    q = torch.take_along_dim(cands, best[..., None, None], dim=-2)[..., 0, :]
    return canonical_sign(normalize(q))


def from_axis_angle(axis: Tensor, angle_rad: Tensor | float) -> Tensor:
    """Quaternions rotating by ``angle_rad`` about ``axis`` (normalised here; need not be unit)."""
    half = 0.5 * _as_like(angle_rad, axis)[..., None]
    return _cat_wv(torch.cos(half), torch.sin(half) * _unit(axis))


def from_rotation_vector(rotvec: Tensor) -> Tensor:
    """Quaternions from rotation vectors (axis · angle), exact and smooth near zero."""
    angle_sq = torch.sum(rotvec * rotvec, dim=-1, keepdim=True)
    small = angle_sq < 1e-12  # angle < 1e-6, as in numpy
    angle = torch.sqrt(torch.where(small, torch.ones_like(angle_sq), angle_sq))
    half = 0.5 * angle
    # Taylor series near zero: cos(a/2) and sin(a/2)/a without dividing by a.
    w = torch.where(small, 1.0 - angle_sq / 8.0 + angle_sq * angle_sq / 384.0, torch.cos(half))
    scale = torch.where(small, 0.5 - angle_sq / 48.0, torch.sin(half) / angle)
    return torch.cat([w, scale * rotvec], dim=-1)


def to_axis_angle(q: Tensor) -> tuple[Tensor, Tensor]:
    """(unit axis (…, 3), angle in [0, π]) of unit quaternions; axis is x̂ for zero rotation."""
    q = canonical_sign(q)
    v = q[..., 1:]
    s_sq = torch.sum(v * v, dim=-1)
    safe = s_sq > _EPS * _EPS
    s = torch.sqrt(torch.where(safe, s_sq, torch.ones_like(s_sq)))
    angle = 2.0 * torch.atan2(torch.where(safe, s, torch.zeros_like(s)), q[..., 0])
    x_hat = torch.zeros_like(v)
    x_hat[..., 0] = 1.0
    axis = torch.where(safe[..., None], v / s[..., None], x_hat)
    return axis, angle


def to_rotation_vector(q: Tensor) -> Tensor:
    """Rotation vectors (axis · angle, angle in [0, π]) of unit quaternions, smooth at zero."""
    q = canonical_sign(q)
    w = q[..., :1]
    v = q[..., 1:]
    s_sq = torch.sum(v * v, dim=-1, keepdim=True)
    small = s_sq < 1e-12  # |v| < 1e-6: use the series of 2·atan(s/w)/s
    s = torch.sqrt(torch.where(small, torch.ones_like(s_sq), s_sq))
    w_safe = torch.where(small & (w > 0.0), w, torch.ones_like(w))
    factor = torch.where(
        small,
        (2.0 / w_safe) * (1.0 - s_sq / (3.0 * w_safe * w_safe)),
        2.0 * torch.atan2(s, w) / s,
    )
    return factor * v


def angle_between(a: Tensor, b: Tensor) -> Tensor:
    """Rotation angle (rad, in [0, π]) of a* ⊗ b: the geodesic distance between rotations."""
    rel = mul(conjugate(a), b)
    # atan2 keeps full precision for tiny angles, where acos of the dot product does not.
    return 2.0 * torch.atan2(_norm(rel[..., 1:]), torch.abs(rel[..., 0]))


def slerp(a: Tensor, b: Tensor, t: Tensor | float) -> Tensor:
    """Spherical linear interpolation from a (t = 0) to b (t = 1) along the shorter arc."""
    tt = _as_like(t, a)[..., None]
    d = torch.sum(a * b, dim=-1, keepdim=True)
    b = torch.where(d < 0.0, -b, b)
    # Angle between the unit 4-vectors from chord lengths: exact and differentiable near 0,
    # where acos(dot) has an infinite derivative.
    theta = 2.0 * torch.atan2(_norm(a - b, keepdim=True), _norm(a + b, keepdim=True))
    sin_theta = torch.sin(theta)
    near = sin_theta < 1e-9
    safe_sin = torch.where(near, torch.ones_like(sin_theta), sin_theta)
    wa = torch.where(near, 1.0 - tt, torch.sin((1.0 - tt) * theta) / safe_sin)
    wb = torch.where(near, tt, torch.sin(tt * theta) / safe_sin)
    return normalize(wa * a + wb * b)


def swing_twist(q: Tensor, axis: Tensor) -> tuple[Tensor, Tensor]:
    """Split q into swing ⊗ twist, twist a rotation about ``axis`` (in q's local frame).

    ``mul(swing, twist)`` reproduces q; swing has no component about ``axis``. When q is a
    half-turn perpendicular to the axis the twist is undefined; identity is returned then.
    """
    u = _unit(axis)
    proj = torch.sum(q[..., 1:] * u, dim=-1, keepdim=True)
    twist = _cat_wv(q[..., :1], proj * u)
    n_sq = torch.sum(twist * twist, dim=-1, keepdim=True)
    degenerate = n_sq < _EPS * _EPS
    n = torch.sqrt(torch.where(degenerate, torch.ones_like(n_sq), n_sq))
    ident = torch.zeros_like(twist)
    ident[..., 0] = 1.0
    twist = torch.where(degenerate, ident, twist / n)
    swing = mul(q, conjugate(twist))
    return swing, twist


def twist_angle(q: Tensor, axis: Tensor) -> Tensor:
    """Signed twist angle (rad, in (−π, π]) of q about ``axis`` (right-hand rule)."""
    proj = torch.sum(q[..., 1:] * _unit(axis), dim=-1)
    angle = 2.0 * _safe_atan2(proj, q[..., 0])
    # Wrap to (−π, π]: q and −q give angles differing by 2π.
    return math.pi - torch.remainder(math.pi - angle, 2.0 * math.pi)


def from_two_vectors(a: Tensor, b: Tensor) -> Tensor:
    """Shortest-arc rotation taking direction a onto direction b (axis a × b, angle
    atan2(|a × b|, a · b)); nearly opposite directions (|a × b| < 1e-8, a · b < 0) turn about a
    fixed axis perpendicular to a, as in the numpy version."""
    shape = np.broadcast_shapes(a.shape, b.shape)
    ua = _unit(a).expand(shape)
    ub = _unit(b).expand(shape)
    d = torch.sum(ua * ub, dim=-1, keepdim=True)
    c = _cross(ua, ub)
    s2 = torch.sum(c * c, dim=-1, keepdim=True)
    # Parallel, or nearly opposite (a × b is rounding noise, and sqrt / division would have no
    # gradient at zero): a fixed perpendicular axis.
    degenerate = (s2 <= torch.finfo(s2.dtype).tiny) | ((s2 < 1e-16) & (d < 0.0))
    s = torch.sqrt(torch.where(degenerate, torch.ones_like(s2), s2))
    half = 0.5 * torch.atan2(torch.where(degenerate, torch.zeros_like(s), s), d)
    x_hat = torch.zeros_like(ua)
    x_hat[..., 0] = 1.0
    y_hat = torch.zeros_like(ua)
    y_hat[..., 1] = 1.0
    helper = torch.where(torch.abs(ua[..., :1]) < 0.9, x_hat, y_hat)
    perp = _unit(_cross(ua, helper))
    axis = torch.where(degenerate, perp, c / s)
    return torch.cat([torch.cos(half), torch.sin(half) * axis], dim=-1)


# --- Euler angles -------------------------------------------------------------------------


def _elementary(axis: int, angle: Tensor) -> Tensor:
    half = 0.5 * angle
    zero = torch.zeros_like(angle)
    parts = [torch.cos(half), zero, zero, zero]
    parts[1 + axis] = torch.sin(half)
    return torch.stack(parts, dim=-1)


def from_euler(angles_rad: Tensor, order: str) -> Tensor:
    """Unit quaternions (…, 4) from Euler angles (…, 3) in radians, in the given order.

    Upper case is intrinsic (``"ZYX"``: R = Rz(a0)·Ry(a1)·Rx(a2), as a BVH channel line), lower
    case extrinsic (``"xyz"``: R = Rz(a2)·Ry(a1)·Rx(a0)).
    """
    axes, intrinsic = parse_order(order)
    if angles_rad.shape[-1:] != (3,):
        raise ValueError(
            f"Euler angles need a last axis of length 3, got shape {tuple(angles_rad.shape)}"
        )
    q0 = _elementary(axes[0], angles_rad[..., 0])
    q1 = _elementary(axes[1], angles_rad[..., 1])
    q2 = _elementary(axes[2], angles_rad[..., 2])
    if intrinsic:
        return mul(mul(q0, q1), q2)
    return mul(mul(q2, q1), q0)


def to_euler(q: Tensor, order: str) -> Tensor:
    """Euler angles (…, 3) in radians of unit quaternions, in the given order.

    Same ranges and gimbal-lock convention as the numpy version: first and last angles in
    (−π, π]; the middle one in [−π/2, π/2] (Tait–Bryan) or [0, π] (proper Euler); at gimbal
    lock the last angle is zero. Bernardes & Viollet (2022), with safe atan2/hypot so the
    gradient stays finite at the lock.
    """
    axes, intrinsic = parse_order(order)
    if q.shape[-1:] != (4,):
        raise ValueError(f"quaternions need a last axis of length 4, got shape {tuple(q.shape)}")
    q = normalize(q)
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
    hyp_cd = torch.sqrt(torch.clamp_min(c * c + d * d, _TINY_SQ))
    hyp_ab = torch.sqrt(torch.clamp_min(a * a + b * b, _TINY_SQ))
    theta2 = 2.0 * torch.atan2(hyp_cd, hyp_ab)
    half_sum = _safe_atan2(b, a)
    half_diff = _safe_atan2(d, c)
    at_zero = torch.abs(theta2) < _GIMBAL_TOL
    at_pi = torch.abs(theta2 - math.pi) < _GIMBAL_TOL
    # theta1 = θ+ − θ−, theta3 = θ+ + θ−. At a lock only their sum (θ2 = 0) or difference
    # (θ2 = π) is defined: put it all in one angle and set the other to 0 — the one that ends
    # up last in the caller's order (theta3 here, theta1 for intrinsic orders, which reverse).
    lock = at_zero | at_pi
    zero = torch.zeros_like(theta2)
    if intrinsic:
        theta1 = torch.where(lock, zero, half_sum - half_diff)
        theta3 = torch.where(
            at_zero, 2.0 * half_sum, torch.where(at_pi, 2.0 * half_diff, half_sum + half_diff)
        )
    else:
        theta1 = torch.where(
            at_zero, 2.0 * half_sum, torch.where(at_pi, -2.0 * half_diff, half_sum - half_diff)
        )
        theta3 = torch.where(lock, zero, half_sum + half_diff)
    if not proper:
        theta3 = eps * theta3
        theta2 = theta2 - 0.5 * math.pi
    out = torch.stack([theta1, theta2, theta3], dim=-1)
    out = math.pi - torch.remainder(math.pi - out, 2.0 * math.pi)  # wrap to (−π, π]
    if intrinsic:
        out = out.flip(-1)
    return out


def matrix_from_euler(angles_rad: Tensor, order: str) -> Tensor:
    """Rotation matrices (…, 3, 3) from Euler angles in radians."""
    return to_matrix(from_euler(angles_rad, order))


def rpy_to_quat(rpy_rad: Tensor) -> Tensor:
    """URDF ``rpy`` (fixed-axis roll about x, pitch about y, yaw about z) to quaternions."""
    return from_euler(rpy_rad, "xyz")


# --- 6D rotation representation (Zhou et al. 2019) --------------------------------------------


def matrix_to_rotation_6d(matrix: Tensor) -> Tensor:
    """The first two columns of rotation matrices (…, 3, 3), concatenated: (…, 6)."""
    return torch.cat([matrix[..., :, 0], matrix[..., :, 1]], dim=-1)


def rotation_6d_to_matrix(d6: Tensor) -> Tensor:
    """Rotation matrices (…, 3, 3) from any 6-vectors by Gram–Schmidt (columns b1, b2, b1×b2).

    Continuous in its input, unlike quaternions or Euler angles, which is why networks regress
    it; the two 3-vectors need not be unit or orthogonal, only not parallel.
    """
    if d6.shape[-1:] != (6,):
        raise ValueError(f"6D rotations need a last axis of length 6, got shape {tuple(d6.shape)}")
    a1 = d6[..., :3]
    a2 = d6[..., 3:]
    b1 = normalize(a1)
    b2 = normalize(a2 - torch.sum(b1 * a2, dim=-1, keepdim=True) * b1)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)


def to_rotation_6d(q: Tensor) -> Tensor:
    """6D representation (…, 6) of unit quaternions (…, 4)."""
    return matrix_to_rotation_6d(to_matrix(q))


def from_rotation_6d(d6: Tensor) -> Tensor:
    """Unit quaternions (w ≥ 0) of 6D rotations (…, 6)."""
    return from_matrix(rotation_6d_to_matrix(d6))
