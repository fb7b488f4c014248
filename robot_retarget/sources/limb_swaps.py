"""Left and right limbs a pose estimator swapped, swapped back by continuity.

The classic estimator confusion labels the left arm (or leg) as the right one for a few frames,
most often when the performer turns side-on or away. Swapped, a limb's every joint jumps across
the body, by at least the shoulder (or hip) width: far more than a joint moves between two frames
of a live sender, and far more than an estimator jitters. So a frame whose left and right chain
sit closer to the previous frame's right and left chain (at most half the squared distance of the
labels as sent) is taken as swapped, and swapped back. If the labels as sent stay "swapped" for
longer than ``max_frames`` (a stream that started swapped, a turn the rule misread), the
sender's labels are believed again: the rule corrects short confusions and never holds a wrong
side for long.

Stateful per stream: :meth:`LimbSwapFix.reset` at a sender restart.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray

# Swap back when the crossed assignment is at most this share of the straight one (squared
# distances summed over the chain): a clear jump, not an ambiguous frame.
SWAP_MARGIN = 0.5
# Longest run of swapped frames corrected (0.5 s at 30 fps, an estimator's rate).
MAX_SWAPPED_FRAMES = 15


class LimbSwapFix:
    """``fix(positions (J, 3))`` → positions with swapped limb pairs swapped back.

    ``pairs``: (left chain, right chain) joint indices, one pair per limb (arms, legs).
    :attr:`swapped` tells, per pair, whether the last frame was swapped back."""

    def __init__(
        self,
        pairs: Sequence[tuple[Sequence[int], Sequence[int]]],
        *,
        max_frames: int = MAX_SWAPPED_FRAMES,
    ) -> None:
        if max_frames < 0:
            raise ValueError(f"max_frames must be ≥ 0, got {max_frames}")
        straight: list[int] = []
        crossed: list[int] = []
        self._spans: list[tuple[int, int]] = []
        for left, right in pairs:
            a, b = [int(i) for i in left], [int(i) for i in right]
            if len(a) != len(b) or not a or set(a) & set(b) or set(a + b) & set(straight):
                raise ValueError(
                    f"a limb pair needs two disjoint chains of equal length, apart from the "
                    f"other pairs: {a}, {b}"
                )
            self._spans.append((len(straight), len(straight) + len(a) + len(b)))
            straight += a + b
            crossed += b + a
        # Both assignments in one gather: the labels as sent, then crossed; the previous
        # output's chains are kept twice over, to be compared with both at once.
        self._both = np.array(straight + crossed, dtype=np.intp)
        self._twice = np.array(straight + straight, dtype=np.intp)
        self._max = int(max_frames)
        self._last: FloatArray | None = None  # the previous output at ``_twice``
        self._runs = [0] * len(self._spans)
        self.swapped = [False] * len(self._spans)

    def reset(self) -> None:
        """A new stream: the next frame's labels are taken as sent."""
        self._last = None
        self._runs = [0] * len(self._spans)
        self.swapped = [False] * len(self._spans)

    def __call__(self, positions: npt.ArrayLike) -> FloatArray:
        p = np.array(positions, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"positions must have shape (J, 3), got {p.shape}")
        last = self._last
        if last is not None:
            n = len(self._both) // 2
            d = p[self._both] - last
            cost = (d * d).sum(axis=1).tolist()
            for k, (lo, hi) in enumerate(self._spans):
                keep, cross = sum(cost[lo:hi]), sum(cost[n + lo : n + hi])
                swap = cross <= SWAP_MARGIN * keep and self._runs[k] < self._max
                self._runs[k] = self._runs[k] + 1 if swap else 0
                self.swapped[k] = swap
                if swap:
                    idx = self._both[lo:hi]
                    p[idx] = p[self._both[n + lo : n + hi]]
        self._last = p[self._twice]
        return p
