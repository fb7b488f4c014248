"""Foot contacts of a motion and foot skate of a retargeted one (numpy only).

A foot joint (ankle or toe) is *in contact* in frames where it is both slow horizontally and
near its lowest height in the clip; the thresholds are in leg lengths so they fit any body.
Foot skate (the papers' and robot retargeting's main artefact) is the target's horizontal
speed of that joint during the *source's* contact frames, in leg lengths per second: 0 when
the target's foot stays planted wherever the performer's did.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.skeleton.canonical import Joint

FOOT_JOINTS: tuple[int, ...] = (
    Joint.LeftFoot,
    Joint.LeftToeBase,
    Joint.RightFoot,
    Joint.RightToeBase,
)

# Contact thresholds, leg lengths: ≈ 0.27 m/s and ≈ 9 cm above the lowest point for a 0.9 m leg.
CONTACT_SPEED_LEGS_S = 0.3
CONTACT_HEIGHT_LEGS = 0.1


def horizontal_speed(positions: npt.ArrayLike, fps: float) -> FloatArray:
    """Horizontal (XZ) speed (T, K) of points (T, K, 3), units/s; frame 0 copies frame 1."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"positions must be (T, K, 3), got {p.shape}")
    if p.shape[0] < 2:
        return np.zeros(p.shape[:2])
    step = np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1) * fps
    return np.concatenate([step[:1], step], axis=0)


def foot_contacts(
    positions: npt.ArrayLike,
    fps: float,
    leg_length_m: float,
    *,
    speed_legs_s: float = CONTACT_SPEED_LEGS_S,
    height_legs: float = CONTACT_HEIGHT_LEGS,
) -> BoolArray:
    """Contact flags (T, 4) for FOOT_JOINTS of global joint positions (T, 22, 3), Y up."""
    p = np.asarray(positions, dtype=np.float64)[:, list(FOOT_JOINTS)]
    speed = horizontal_speed(p, fps)
    height = p[..., 1] - p[..., 1].min(axis=0, keepdims=True)
    return np.asarray(
        (speed < speed_legs_s * leg_length_m) & (height < height_legs * leg_length_m),
        dtype=np.bool_,
    )


def foot_skate(
    target_positions: npt.ArrayLike,
    contacts: npt.ArrayLike,
    fps: float,
    target_leg_length_m: float,
) -> float:
    """Mean horizontal speed (leg lengths/s) of the target's foot joints over the contact
    frames ``contacts`` (T, 4) (the source's); NaN when there is no contact frame."""
    c = np.asarray(contacts, dtype=np.bool_)
    p = np.asarray(target_positions, dtype=np.float64)[:, list(FOOT_JOINTS)]
    if c.shape != p.shape[:2]:
        raise ValueError(f"contacts must be {p.shape[:2]}, got {c.shape}")
    if not c.any():
        return float("nan")
    speed = horizontal_speed(p, fps) / target_leg_length_m
    return float(speed[c].mean())
