"""The line ``convert`` and ``stream`` print when the solver failed on many frames.

A frame the solver fails on holds the previous command (safe, but the robot stops following).
A few in a long run are the optimizer's business; many at once are nearly always a robot
config whose geometry contradicts itself (a bone whose start and end are swapped, a reversed
``forward_axis``), where every solve meets a NaN derivative from the first frame on.
"""

from __future__ import annotations

SHARE = 0.1
"""Fallbacks on at least this share of the frames earn the warning (none of the shipped robots'
runs on the shared clips comes near: 0 fallbacks in their `eval-robot` tables)."""


def fallback_warning(fallbacks: int, frames: int) -> str | None:
    """The warning for ``fallbacks`` of ``frames``, or None when there are few."""
    if frames <= 0 or fallbacks < SHARE * frames:
        return None
    return (
        f"warning: the solver failed on {fallbacks} of {frames} frames, which held the "
        "previous command (the robot stops following); with your own robot config, check "
        "that each bone runs from its start toward its end along the limb and that up_axis "
        "and forward_axis point up and forward"
    )
