"""Hard joint limits as one box per frame, and the projection that enforces them.

The box merges position limits with the velocity limit around the previous command:
``[max(lower, q_prev − v·dt), min(upper, q_prev + v·dt)]``. When q_prev lies outside the limits
(a robot switched on in an odd pose) that interval can be empty; the box then collapses to the
one point q_prev ± v·dt that moves toward the limits at full speed, so recovery never asks for a
jump and never stalls. Everything here is plain numpy: it is the last line of defence, applied
to every solver output, feasible or not.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import FloatArray


def velocity_box(
    q_prev: FloatArray, lower: FloatArray, upper: FloatArray, step: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(lo, hi) of the merged box for the next frame; ``step`` = v_max·dt (rad)."""
    lo = np.maximum(lower, q_prev - step)
    hi = np.minimum(upper, q_prev + step)
    empty = lo > hi
    if np.any(empty):
        # Above the upper limit: lo = q_prev − step is the move toward the limits; below: hi.
        above = q_prev > upper
        lo = np.where(empty & ~above, hi, lo)
        hi = np.where(empty & above, lo, hi)
    return lo, hi


def project_sequence(
    q: FloatArray, q_prev: FloatArray, lower: FloatArray, upper: FloatArray, step: FloatArray
) -> FloatArray:
    """Clip frames (T, J) one after the other into the box around the previous clipped frame."""
    out = np.empty_like(q)
    prev = q_prev
    for t in range(q.shape[0]):
        lo, hi = velocity_box(prev, lower, upper, step)
        out[t] = np.minimum(np.maximum(q[t], lo), hi)
        prev = out[t]
    return out


def box_violation(q: FloatArray, lo: FloatArray, hi: FloatArray) -> float:
    """Largest distance (rad) of q outside [lo, hi]; 0 inside."""
    return float(max(np.max(lo - q), np.max(q - hi), 0.0))
