"""The performer's trunk frame: the body frame the robot's trunk copies, heading and lean.

Columns forward, left, up in canonical coordinates (X left, Y up, Z forward): up runs from the
hip midpoint to the shoulder midpoint (the torso as eval-robot scores it), left is the hips'
right → left axis made perpendicular to it, forward = left × up. It is built from joint
positions, not from the root joint's rotation: BVH exporters orient the Hips joint as they
please (a DAZ rig's Hips sit ≈ 10–15° off its torso), a skeleton's positions mean the same
everywhere. The optimizer's targets are expressed in this frame and the floating base turns
and tilts with it, so the robot's trunk leans as the performer's torso does and every limb
stands in the world where the performer's does.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.canonical import Joint

_EPS = 1e-9
_UP = np.array([0.0, 1.0, 0.0])
_LEFT = np.array([1.0, 0.0, 0.0])


def trunk_frames(hip_axis: npt.ArrayLike, trunk: npt.ArrayLike) -> FloatArray:
    """(…, 3, 3) frames from the hips' right → left vector and the hip → shoulder vector (…, 3).

    Degenerate input falls back to the canonical axes: a zero trunk to up, a hip axis along
    the trunk to the canonical left made perpendicular (or, failing that, forward × up)."""
    h = np.asarray(hip_axis, dtype=np.float64)
    t = np.asarray(trunk, dtype=np.float64)
    up = _unit(t, _UP)
    left = h - up * np.sum(h * up, axis=-1, keepdims=True)
    fallback = _LEFT - up * np.sum(_LEFT * up, axis=-1, keepdims=True)
    left = _unit(left, _unit(fallback, np.cross(up, np.array([0.0, 0.0, 1.0]))))
    # A second pass: with the hips nearly along the trunk the first leaves ~1e-8 of up in left.
    left = _unit(left - up * np.sum(left * up, axis=-1, keepdims=True), left)
    fwd = np.cross(left, up)
    return np.stack([fwd, left, up], axis=-1)


def trunk_frame(hip_axis: FloatArray, trunk: FloatArray) -> FloatArray:
    """One frame of :func:`trunk_frames` from (3,) vectors, in plain floats: the live path calls
    this every control tick, where numpy's per-call overhead on 3-vectors costs ≈ 10× more."""
    tx, ty, tz = float(trunk[0]), float(trunk[1]), float(trunk[2])
    n = math.sqrt(tx * tx + ty * ty + tz * tz)
    if not n > _EPS:
        return trunk_frames(hip_axis, trunk)
    ux, uy, uz = tx / n, ty / n, tz / n
    hx, hy, hz = float(hip_axis[0]), float(hip_axis[1]), float(hip_axis[2])
    d = hx * ux + hy * uy + hz * uz
    lx, ly, lz = hx - d * ux, hy - d * uy, hz - d * uz
    m = math.sqrt(lx * lx + ly * ly + lz * lz)
    if not m > _EPS:
        return trunk_frames(hip_axis, trunk)
    lx, ly, lz = lx / m, ly / m, lz / m
    d = lx * ux + ly * uy + lz * uz  # second pass, as in trunk_frames
    lx, ly, lz = lx - d * ux, ly - d * uy, lz - d * uz
    m = math.sqrt(lx * lx + ly * ly + lz * lz)
    lx, ly, lz = lx / m, ly / m, lz / m
    # forward = left × up
    fx, fy, fz = ly * uz - lz * uy, lz * ux - lx * uz, lx * uy - ly * ux
    return np.array(((fx, lx, ux), (fy, ly, uy), (fz, lz, uz)))


def trunk_frames_of_positions(positions: npt.ArrayLike) -> FloatArray:
    """(T, 3, 3) trunk frames of canonical global joint positions (T, 22, 3)."""
    p = np.asarray(positions, dtype=np.float64)
    hips = 0.5 * (p[:, Joint.LeftUpLeg] + p[:, Joint.RightUpLeg])
    shoulders = 0.5 * (p[:, Joint.LeftArm] + p[:, Joint.RightArm])
    return trunk_frames(p[:, Joint.LeftUpLeg] - p[:, Joint.RightUpLeg], shoulders - hips)


def _unit(v: FloatArray, fallback: FloatArray) -> FloatArray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = n > _EPS
    return np.asarray(np.where(ok, v / np.where(ok, n, 1.0), fallback), dtype=np.float64)
