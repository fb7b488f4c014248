"""A built-in motion clip the project generates itself: the demo's input, needing no data files.

A 12-second routine on the canonical skeleton (Y up, facing +Z, left = +X) that exercises every
limb the way people do in front of a robot: a wave, a two-handed reach, a squat, side steps with
a turn, alternating punches and a look around. Each joint's rotation is a product of elementary
rotations whose angles follow key frames with smooth (C¹) blending, plus small oscillations, so
the motion has realistic velocities rather than jumps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}

# Arms hang 75° below the T-pose when relaxed; elbows slightly bent.
_ARM_DOWN_DEG = 75.0


@dataclass(frozen=True)
class _Channel:
    """One elementary rotation of a joint: angle (deg) at key times (s), blended smoothly."""

    joint: str
    axis: str
    times_s: tuple[float, ...]
    angles_deg: tuple[float, ...]


def _keys(*pairs: tuple[float, float]) -> tuple[tuple[float, ...], tuple[float, ...]]:
    return tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)


def _channel(joint: str, axis: str, *pairs: tuple[float, float]) -> _Channel:
    times, angles = _keys(*pairs)
    return _Channel(joint, axis, times, angles)


# Phases (seconds): 0–2 wave, 2–4 reach, 4–6.5 squat, 6.5–9 side steps + turn, 9–11 punches,
# 11–12 look around and settle. Angles in degrees, per the sign conventions in the docstring.
_CHANNELS: tuple[_Channel, ...] = (
    # Left arm: down, reach forward, guard for punches, down.
    _channel("LeftArm", "z", (0, -_ARM_DOWN_DEG), (2.2, -_ARM_DOWN_DEG), (3.0, 0.0), (4.0, 0.0),
             (4.6, -_ARM_DOWN_DEG), (8.6, -_ARM_DOWN_DEG), (9.2, -60.0), (11.0, -60.0),
             (11.6, -_ARM_DOWN_DEG), (12, -_ARM_DOWN_DEG)),
    _channel("LeftArm", "y", (0, 0.0), (2.2, 0.0), (3.0, -85.0), (4.0, -85.0), (4.6, -30.0),
             (6.5, -30.0), (7.0, 0.0), (9.0, 0.0), (9.2, -70.0), (9.6, -90.0), (9.9, -70.0),
             (10.4, -90.0), (10.7, -70.0), (11.0, -70.0), (11.6, 0.0), (12, 0.0)),
    _channel("LeftForeArm", "y", (0, -10.0), (2.2, -10.0), (3.0, -5.0), (4.0, -5.0),
             (4.6, -20.0), (9.2, -100.0), (9.6, -10.0), (9.9, -100.0), (10.4, -10.0),
             (10.7, -100.0), (11.0, -100.0), (11.6, -10.0), (12, -10.0)),
    # Right arm: wave (raised sideways, forearm swinging), reach, punches.
    _channel("RightArm", "z", (0, _ARM_DOWN_DEG), (0.5, -50.0), (1.8, -50.0), (2.2, _ARM_DOWN_DEG),
             (2.2, _ARM_DOWN_DEG), (3.0, 0.0), (4.0, 0.0), (4.6, _ARM_DOWN_DEG),
             (8.6, _ARM_DOWN_DEG), (9.2, 60.0), (11.0, 60.0), (11.6, _ARM_DOWN_DEG),
             (12, _ARM_DOWN_DEG)),
    _channel("RightArm", "y", (0, 0.0), (2.2, 0.0), (3.0, 85.0), (4.0, 85.0), (4.6, 30.0),
             (6.5, 30.0), (7.0, 0.0), (9.0, 0.0), (9.2, 70.0), (9.4, 90.0), (9.75, 70.0),
             (10.1, 90.0), (10.55, 70.0), (10.85, 90.0), (11.0, 70.0), (11.6, 0.0), (12, 0.0)),
    _channel("RightForeArm", "z", (0, 0.0), (0.5, -45.0), (0.8, -80.0), (1.1, -20.0),
             (1.4, -80.0), (1.7, -20.0), (1.9, -45.0), (2.2, 0.0), (12, 0.0)),
    _channel("RightForeArm", "y", (0, 10.0), (2.2, 10.0), (3.0, 5.0), (4.0, 5.0), (4.6, 20.0),
             (9.2, 100.0), (9.4, 10.0), (9.75, 100.0), (10.1, 10.0), (10.55, 100.0),
             (10.85, 10.0), (11.15, 100.0), (11.6, 10.0), (12, 10.0)),
    # Torso: lean into the squat, twist with the punches.
    _channel("Spine", "x", (0, 0.0), (4.0, 0.0), (5.0, 20.0), (5.6, 20.0), (6.5, 0.0), (12, 0.0)),
    _channel("Spine1", "y", (0, 0.0), (9.2, 0.0), (9.6, 15.0), (9.9, -15.0), (10.4, 15.0),
             (10.7, -15.0), (11.0, 0.0), (12, 0.0)),
    # Head: look at the waving hand, then around.
    _channel("Head", "y", (0, 0.0), (0.5, -25.0), (1.9, -25.0), (2.4, 0.0), (11.0, 0.0),
             (11.3, 35.0), (11.6, -35.0), (12, 0.0)),
    _channel("Neck", "x", (0, 0.0), (0.5, -10.0), (1.9, -10.0), (2.4, 0.0), (4.0, 0.0),
             (5.0, 15.0), (5.6, 15.0), (6.5, 0.0), (12, 0.0)),
    # Legs: squat (thigh forward α, knee 2α, ankle back −α keeps the feet flat) and steps.
    _channel("LeftUpLeg", "x", (0, 0.0), (4.0, 0.0), (5.0, -60.0), (5.6, -60.0), (6.5, 0.0),
             (6.9, -25.0), (7.3, 0.0), (8.1, -25.0), (8.5, 0.0), (12, 0.0)),
    _channel("LeftLeg", "x", (0, 0.0), (4.0, 0.0), (5.0, 120.0), (5.6, 120.0), (6.5, 0.0),
             (6.9, 50.0), (7.3, 0.0), (8.1, 50.0), (8.5, 0.0), (12, 0.0)),
    _channel("LeftFoot", "x", (0, 0.0), (4.0, 0.0), (5.0, -60.0), (5.6, -60.0), (6.5, 0.0),
             (6.9, -25.0), (7.3, 0.0), (8.1, -25.0), (8.5, 0.0), (12, 0.0)),
    _channel("LeftUpLeg", "z", (0, 0.0), (6.5, 0.0), (6.9, 12.0), (7.3, 0.0), (12, 0.0)),
    _channel("RightUpLeg", "x", (0, 0.0), (4.0, 0.0), (5.0, -60.0), (5.6, -60.0), (6.5, 0.0),
             (7.3, 0.0), (7.7, -25.0), (8.1, 0.0), (8.5, 0.0), (8.9, -25.0), (9.3, 0.0), (12, 0.0)),
    _channel("RightLeg", "x", (0, 0.0), (4.0, 0.0), (5.0, 120.0), (5.6, 120.0), (6.5, 0.0),
             (7.3, 0.0), (7.7, 50.0), (8.1, 0.0), (8.5, 0.0), (8.9, 50.0), (9.3, 0.0), (12, 0.0)),
    _channel("RightFoot", "x", (0, 0.0), (4.0, 0.0), (5.0, -60.0), (5.6, -60.0), (6.5, 0.0),
             (7.3, 0.0), (7.7, -25.0), (8.1, 0.0), (8.5, 0.0), (8.9, -25.0), (9.3, 0.0), (12, 0.0)),
    _channel("RightUpLeg", "z", (0, 0.0), (7.3, 0.0), (7.7, -12.0), (8.1, 0.0), (12, 0.0)),
    # Root: turn left during the side steps and back.
    _channel("Hips", "y", (0, 0.0), (6.5, 0.0), (8.0, 45.0), (9.0, 45.0), (11.0, 0.0), (12, 0.0)),
)  # fmt: skip


def _smooth_keys(t: FloatArray, times: tuple[float, ...], values: tuple[float, ...]) -> FloatArray:
    """Piecewise smoothstep interpolation: C¹, zero velocity at each key, constant outside."""
    k = np.asarray(times, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    out = np.empty_like(t)
    idx = np.clip(np.searchsorted(k, t, side="right") - 1, 0, len(k) - 1)
    nxt = np.minimum(idx + 1, len(k) - 1)
    span = k[nxt] - k[idx]
    u = np.where(span > 0, (t - k[idx]) / np.where(span > 0, span, 1.0), 0.0)
    u = np.clip(u, 0.0, 1.0)
    s = u * u * (3.0 - 2.0 * u)
    out[:] = v[idx] + (v[nxt] - v[idx]) * s
    return out


def demo_motion(fps: float = 30.0, skeleton: Skeleton | None = None) -> HumanMotion:
    """The built-in 12 s demo routine as a HumanMotion (default: a 1.7 m adult skeleton)."""
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    skel = default_canonical_skeleton() if skeleton is None else skeleton
    duration_s = 12.0
    t = np.arange(round(duration_s * fps) + 1) / fps
    local = quat.identity((t.size, len(CANONICAL_JOINTS)))
    for ch in _CHANNELS:
        angle = np.radians(_smooth_keys(t, ch.times_s, ch.angles_deg))
        j = CANONICAL_JOINTS.index(ch.joint)
        local[:, j] = quat.mul(local[:, j], quat.from_axis_angle(_AXES[ch.axis], angle))

    rest = skel.rest_positions()
    # Hips height above the lowest rest point (the toes), so the feet start on the ground y = 0.
    leg_len = float(rest[0, 1] - rest[:, 1].min())
    thigh = float(np.linalg.norm(skel.offsets[CANONICAL_JOINTS.index("LeftLeg")]))
    shin = float(np.linalg.norm(skel.offsets[CANONICAL_JOINTS.index("LeftFoot")]))
    squat = np.radians(-_smooth_keys(t, *_keys((0, 0.0), (4.0, 0.0), (5.0, -60.0), (5.6, -60.0),
                                                 (6.5, 0.0), (12, 0.0))))  # fmt: skip
    root = np.zeros((t.size, 3))
    # Feet stay flat: the hips drop by what the bent thighs and shins lose in height.
    root[:, 1] = leg_len - (thigh + shin) * (1.0 - np.cos(squat))
    # Side steps to the left and back while turning, plus a gentle sway when waving.
    root[:, 0] = 0.15 * _smooth_keys(t, *_keys((0, 0.0), (6.5, 0.0), (8.5, 1.0), (9.3, 1.0),
                                               (11.0, 0.0), (12, 0.0)))  # fmt: skip
    root[:, 0] += 0.01 * np.sin(2 * np.pi * t) * (t < 2.2)
    return HumanMotion(
        skeleton=skel,
        local_quats=local,
        root_pos=root,
        fps=fps,
        source_path=None,
        name_family="built-in demo",
        unit="m",
    )
