"""Live-input corruption modelled on pose estimators and mocap dropouts (numpy only).

What reaches ``stream`` from a camera or a mocap system is not a clean clip: 3D joint positions
that jitter (most at the wrists and ankles, where 2D keypoint error is largest and depth is
least observed), joints that freeze or vanish for a moment (occlusion, a marker lost), left and
right limbs swapped for a few frames (the classic estimator confusion), bones whose length
changes from frame to frame (per-frame depth/scale error), frames that arrive late, and a
camera rate (30 fps) below the control rate (OP3: 125 Hz). Each kind here turns a clean
motion into what such a sender would deliver: positions and the sender's timestamps, with
frames left out where the sender went silent.

Severities (``severity`` = 1) follow published error levels of off-the-shelf 3D pose
estimators (tens of millimetres mean per-joint error): jitter σ = 1 % of the height on the
trunk (≈ 17 mm for a 1.7 m performer) and 2.5× that at wrists, hands, ankles and feet;
dropouts of 1–30 frames; swaps of 1–10 frames; 5 % bone-length noise; 2–4 frames of latency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.motion.human_motion import HumanMotion, skeleton_height
from robot_retarget.skeleton.canonical import (
    ARM_CHAINS,
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    LEG_CHAINS,
    Joint,
)

KINDS: tuple[str, ...] = (
    "jitter",
    "dropout",
    "swap",
    "bone_length",
    "latency",
    "low_rate",
)

JITTER_SIGMA_FRAC = 0.01
_DISTAL = (
    Joint.LeftHand, Joint.RightHand, Joint.LeftForeArm, Joint.RightForeArm,
    Joint.LeftFoot, Joint.RightFoot, Joint.LeftToeBase, Joint.RightToeBase,
)  # fmt: skip
_DISTAL_GAIN = 2.5
_MIDDLE = (Joint.LeftLeg, Joint.RightLeg, Joint.LeftArm, Joint.RightArm)
_MIDDLE_GAIN = 1.5
DROPOUT_FRAMES = (1, 30)
SWAP_FRAMES = (1, 10)
BONE_SIGMA = 0.05
_LATENCY_FRAMES = (2, 4)
_LOW_RATE_HZ = 30.0


@dataclass(frozen=True)
class CorruptedStream:
    """What a live sender delivers: canonical joint positions (N, 22, 3) in metres (Y up) at
    the sender's timestamps ``t_s`` (N,) in seconds; ``kind`` names the corruption."""

    positions: FloatArray
    t_s: FloatArray
    kind: str

    def __post_init__(self) -> None:
        if self.positions.shape != (len(self.t_s), len(CANONICAL_JOINTS), 3):
            raise ValueError(f"positions {self.positions.shape} do not match {len(self.t_s)} times")


def _intervals(
    rng: np.random.Generator, n: int, lengths: tuple[int, int], share: float
) -> list[tuple[int, int]]:
    """Random [start, stop) intervals with lengths in ``lengths`` covering ≈ ``share`` of n."""
    out: list[tuple[int, int]] = []
    covered = 0
    while covered < share * n:
        length = int(rng.integers(lengths[0], lengths[1] + 1))
        start = int(rng.integers(0, max(1, n - length)))
        out.append((start, min(n, start + length)))
        covered += length
    return out


def jitter_gains() -> FloatArray:
    """(J,) each joint's jitter σ as a multiple of the trunk's: 2.5 at the distal joints, 1.5
    at elbows and knees, 1 elsewhere."""
    gain = np.ones(len(CANONICAL_JOINTS))
    gain[list(_DISTAL)] = _DISTAL_GAIN
    gain[list(_MIDDLE)] = _MIDDLE_GAIN
    return gain


def _jitter(pos: FloatArray, height_m: float, rng: np.random.Generator, severity: float) -> None:
    sigma = JITTER_SIGMA_FRAC * height_m * severity * jitter_gains()
    pos += rng.normal(size=pos.shape) * sigma[None, :, None]


def _freeze_joints(pos: FloatArray, rng: np.random.Generator, severity: float) -> None:
    """Occluded joints hold their last seen position (what trackers do) for 1–30 frames."""
    n = len(pos)
    for joint in rng.choice(np.arange(1, len(CANONICAL_JOINTS)), size=6, replace=False):
        for start, stop in _intervals(rng, n, DROPOUT_FRAMES, 0.05 * severity):
            pos[start:stop, joint] = pos[max(start - 1, 0), joint]


def _swap(pos: FloatArray, rng: np.random.Generator, severity: float) -> None:
    for left, right in (ARM_CHAINS, LEG_CHAINS):
        for start, stop in _intervals(rng, len(pos), SWAP_FRAMES, 0.03 * severity):
            a, b = list(left), list(right)
            pos[start:stop, a + b] = pos[start:stop, b + a]


def _bone_lengths(pos: FloatArray, rng: np.random.Generator, severity: float) -> FloatArray:
    """Every bone vector scaled by its own (1 + N(0, 5 %)) per frame, rebuilt root outward."""
    out = pos.copy()
    scale = 1.0 + rng.normal(0.0, BONE_SIGMA * severity, size=pos.shape[:2])
    for j, parent in enumerate(CANONICAL_PARENTS):
        if parent >= 0:
            out[:, j] = out[:, parent] + (pos[:, j] - pos[:, parent]) * scale[:, j, None]
    return out


def corrupt_stream(
    motion: HumanMotion, kind: str, rng: np.random.Generator, *, severity: float = 1.0
) -> CorruptedStream:
    """``motion`` as a live sender of ``kind`` would deliver it (see the module docstring)."""
    if kind not in KINDS and kind != "clean":
        raise ValueError(f"unknown corruption {kind!r}; choose one of {', '.join(KINDS)}")
    if not (np.isfinite(severity) and severity >= 0.0):
        raise ValueError(f"severity must be a finite number ≥ 0, got {severity}")
    pos = motion.positions().copy()
    n = len(pos)
    t = np.arange(n) / motion.fps
    keep = np.ones(n, dtype=bool)
    if kind == "jitter":
        _jitter(pos, skeleton_height(motion.skeleton), rng, severity)
    elif kind == "dropout":
        _freeze_joints(pos, rng, severity)
        for start, stop in _intervals(rng, n, DROPOUT_FRAMES, 0.05 * severity):
            keep[start:stop] = False  # the sender is silent: no frame at all
        keep[0] = True
    elif kind == "swap":
        _swap(pos, rng, severity)
    elif kind == "bone_length":
        pos = _bone_lengths(pos, rng, severity)
    elif kind == "latency":
        delay = int(rng.integers(_LATENCY_FRAMES[0], _LATENCY_FRAMES[1] + 1))
        # The frame stamped t shows the performer at t − delay: the estimator's processing lag.
        pos = np.concatenate([np.repeat(pos[:1], delay, axis=0), pos[: n - delay]])
    elif kind == "low_rate":
        step = max(1, round(motion.fps / _LOW_RATE_HZ))
        keep[:] = False
        keep[::step] = True
    return CorruptedStream(pos[keep], t[keep], kind)
