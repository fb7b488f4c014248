"""A bound for live filtering: a sender's stream smoothed with no lag, as no live filter can.

``eval-robot --corrupt … --oracle-smoothing MS`` smooths each sender's stream with a centred
Gaussian over its timestamps before the live source sees it. A centred kernel averages the
frames after each frame as much as those before it, so it removes jitter without the lag every
causal filter pays for it: the result bounds what any filter in front of the control loop could
do for that bandwidth, and it is not something ``stream`` could run. Each bone's direction and
length, and the root's position, are smoothed on their own, then the frame is rebuilt root
outward (smoothing joint positions on their own would bend bones that the sender kept rigid).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.live_corruption import CorruptedStream
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS

_KERNEL_SIGMAS = 4.0  # frames farther than this many σ get no weight
_SHORT_BONE_M = 1e-6  # a bone this short has no direction: it is kept as sent


class GaussianKernel:
    """A centred Gaussian of σ ``sigma_s`` over the times ``t_s`` (sorted; uneven spacing and
    gaps are weighted by time, not by frame count), row-normalised, held as a band: each
    frame's weights on the frames within 4σ of it. A dense (N, N) matrix had needed 3 GB for a
    3-minute clip at 120 fps; the band is N × (the most frames in 8σ)."""

    def __init__(self, t_s: npt.ArrayLike, sigma_s: float) -> None:
        t = np.asarray(t_s, dtype=np.float64)
        if not (math.isfinite(sigma_s) and sigma_s > 0.0):
            raise ValueError(f"sigma must be a finite number of seconds > 0, got {sigma_s}")
        # The cut-off's margin keeps a kernel symmetric where float division puts a frame at
        # exactly 4σ on one side a hair inside and on the other a hair outside.
        reach = _KERNEL_SIGMAS + 1e-9
        window = (reach + 1e-6) * sigma_s  # a hair wider: the test on d below decides
        lo = np.searchsorted(t, t - window, side="left")
        hi = np.searchsorted(t, t + window, side="right")
        width = int((hi - lo).max()) if len(t) else 0
        index = lo[:, None] + np.arange(width)[None, :]
        inside = index < hi[:, None]
        self.index = np.minimum(index, max(len(t) - 1, 0))
        d = (t[:, None] - t[self.index]) / sigma_s
        w = np.where(inside & (np.abs(d) <= reach), np.exp(-0.5 * d * d), 0.0)
        self.weights = w / w.sum(axis=1, keepdims=True)

    def __call__(self, x: npt.ArrayLike) -> FloatArray:
        """(N, …) values smoothed along their first axis."""
        a = np.asarray(x, dtype=np.float64)[self.index]  # (N, width, …)
        w = self.weights.reshape(self.weights.shape + (1,) * (a.ndim - 2))
        return np.asarray((w * a).sum(axis=1), dtype=np.float64)

    def dense(self) -> FloatArray:
        """The (N, N) weight matrix the band stands for."""
        n = len(self.index)
        out = np.zeros((n, n))
        np.add.at(out, (np.arange(n)[:, None], self.index), self.weights)
        return out


def zero_lag_smoothed(stream: CorruptedStream, sigma_s: float) -> CorruptedStream:
    """``stream`` with every bone's direction and length and the root's position smoothed by a
    centred Gaussian of σ ``sigma_s`` seconds over the sender's timestamps (see the module
    docstring)."""
    w = GaussianKernel(stream.t_s, sigma_s)
    pos = stream.positions
    out = np.empty_like(pos)
    out[:, 0] = w(pos[:, 0])
    for j, parent in enumerate(CANONICAL_PARENTS):
        if parent < 0:
            continue
        bone = pos[:, j] - pos[:, parent]
        length = np.linalg.norm(bone, axis=1)
        has_direction = length > _SHORT_BONE_M
        unit = bone / np.where(has_direction, length, 1.0)[:, None]
        direction = w(np.where(has_direction[:, None], unit, 0.0))
        norm = np.linalg.norm(direction, axis=1)
        # Directions that cancel out (a joint on its parent, seen through jitter) keep their
        # average, shrunk as it is, as the live filter does: kept as sent, they would carry
        # the parent's raw jitter into everything above it.
        scale = np.where(norm > 0.5, norm, 1.0)
        rebuilt = direction / scale[:, None] * w(length)[:, None]
        out[:, j] = out[:, parent] + np.where(has_direction[:, None], rebuilt, bone)
    return CorruptedStream(out, stream.t_s.copy(), stream.kind)
