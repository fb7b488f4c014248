"""The frame rates a motion can plausibly have: a file or option outside them is a mistake
(a Frame Time in the wrong unit, a typo), and resampling to it would build millions of frames."""

from __future__ import annotations

import math
import numbers

MIN_FPS = 1.0
MAX_FPS = 1000.0  # the fastest mocap systems and robot control rates
FPS_RANGE = f"{MIN_FPS:g}–{MAX_FPS:g} frames per second"


def plausible_fps(fps: object) -> bool:
    """Whether ``fps`` is a real number (not a bool) within :data:`MIN_FPS` … :data:`MAX_FPS`."""
    if isinstance(fps, bool) or not isinstance(fps, numbers.Real):
        return False
    try:
        value = float(fps)
    except OverflowError:  # an integer too large for a float
        return False
    return math.isfinite(value) and MIN_FPS <= value <= MAX_FPS
