"""Detect synthetic T-pose frames that converters prepend to a clip.

The cgspeed CMU conversion starts every clip with a frame whose joint rotations are almost all
exactly zero (a few whole-degree leg/arm corrections, ≤ 21°) and which then jumps to the real
first pose (≥ 58° on the 56 clips here, while real motion moves ≤ 7° per frame in median).
One clip (07_12) even has two such frames. A frame counts as synthetic when

- at least ``MIN_ZERO_FRACTION`` of its rotation channels are zero and none exceeds
  ``MAX_TPOSE_DEG``, and
- the step out of the synthetic block is larger than both ``MIN_JUMP_DEG`` and
  ``JUMP_FACTOR`` × the median step of the frames that follow.

The DAZ conversion's first frame (≈ 60 % zeros, then a smooth ramp) is real and is kept.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.motion.bvh import BvhClip

MIN_ZERO_FRACTION = 0.8
MAX_TPOSE_DEG = 45.0
MIN_JUMP_DEG = 15.0
JUMP_FACTOR = 5.0
MAX_SYNTHETIC_FRAMES = 3
_FOLLOWING_STEPS = 10


def _rotation_columns(clip: BvhClip) -> list[int]:
    return [
        clip.channel_start[j] + k
        for j, chans in enumerate(clip.channels)
        for k, c in enumerate(chans)
        if c.endswith("rotation")
    ]


def count_synthetic_tpose_frames(clip: BvhClip) -> int:
    """Number of leading synthetic T-pose frames (0 when the clip starts with real motion)."""
    cols = _rotation_columns(clip)
    if not cols or clip.num_frames < 3:
        return 0
    limit = min(clip.num_frames, MAX_SYNTHETIC_FRAMES + _FOLLOWING_STEPS + 2)
    rot = clip.motion[:limit, cols]
    near_zero = np.abs(rot) < 1e-6
    candidate = (near_zero.mean(axis=1) >= MIN_ZERO_FRACTION) & (
        np.abs(rot).max(axis=1) <= MAX_TPOSE_DEG
    )
    block = 0
    while block < min(MAX_SYNTHETIC_FRAMES, limit - 2) and candidate[block]:
        block += 1
    if block == 0:
        return 0
    # Wrap angle differences so a 179° → −179° step counts as 2°.
    steps = np.abs((np.diff(rot, axis=0) + 180.0) % 360.0 - 180.0).max(axis=1)
    jump = steps[block - 1]
    following = steps[block:]
    if following.size == 0:
        return 0
    typical = float(np.median(following))
    return block if jump > max(MIN_JUMP_DEG, JUMP_FACTOR * typical) else 0
