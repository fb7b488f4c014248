"""Left and right limbs a pose estimator swapped, swapped back by continuity.

The classic estimator confusion labels the left arm (or leg) as the right one for a few frames,
most often when the performer turns side-on or away. Swapped, a limb's every joint jumps across
the body, by at least the shoulder (or hip) width: far more than a joint moves between two frames
of a live sender, and far more than an estimator jitters. So a frame whose left and right chain
sit closer to the previous frame's right and left chain (at most half the squared distance of the
labels as sent) is taken as swapped, and swapped back.

Continuity cannot tell which labels were right to begin with, so the rule is bounded in time:

- a run of frames swapped back ends after ``max_swap_s`` (0.5 s): from then on the labels as sent
  are believed (a stream that started swapped, a swap longer than an estimator's confusions),
  and their next crossing within another ``max_swap_s`` is taken as the sender's own return to
  the other labels, not corrected. A swap longer than ``max_swap_s`` is therefore corrected for
  its first ``max_swap_s`` and then passes as sent, and a stream that started swapped is
  followed on its wrong side for at most ``max_swap_s``;
- after a silence longer than ``max_gap_s`` (0.25 s) the previous frame says nothing about the
  next (the performer may have turned round meanwhile): the next frame's labels are taken as
  sent, as are those of a frame whose timestamp went back (a sender restart).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray

# Swap back when the crossed assignment is at most this share of the straight one (squared
# distances summed over the chain): a clear jump, not an ambiguous frame.
SWAP_MARGIN = 0.5
MAX_SWAP_S = 0.5  # the longest swap corrected
MAX_GAP_S = 0.25  # a silence after which the last frame is no reference


class LimbSwapFix:
    """``fix(positions (J, 3), t_s)`` → positions with swapped limb pairs swapped back.

    ``pairs``: (left chain, right chain) joint indices, one pair per limb (arms, legs); ``t_s``
    is the sender's timestamp (seconds). :attr:`swapped` tells, per pair, whether the last
    frame was swapped back."""

    def __init__(
        self,
        pairs: Sequence[tuple[Sequence[int], Sequence[int]]],
        *,
        max_swap_s: float = MAX_SWAP_S,
        max_gap_s: float = MAX_GAP_S,
    ) -> None:
        if not (max_swap_s >= 0.0 and max_gap_s >= 0.0):
            raise ValueError(f"max_swap_s and max_gap_s must be ≥ 0, got {max_swap_s}, {max_gap_s}")
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
        self._max_swap = float(max_swap_s)
        self._max_gap = float(max_gap_s)
        self.reset()

    def reset(self) -> None:
        """A new stream: the next frame's labels are taken as sent."""
        n = len(self._spans)
        self._last: FloatArray | None = None  # the previous output at ``_twice``
        self._last_t = 0.0
        self._run_start: list[float | None] = [None] * n  # when the current run began
        self._believed_at: list[float | None] = [None] * n  # when a run ran out
        self.swapped = [False] * n

    def __call__(self, positions: npt.ArrayLike, t_s: float) -> FloatArray:
        p = np.array(positions, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"positions must have shape (J, 3), got {p.shape}")
        t = float(t_s)
        if self._last is not None and not 0.0 < t - self._last_t <= self._max_gap:
            self.reset()  # a silence, or a sender restart: no reference
        last = self._last
        if last is not None:
            n = len(self._both) // 2
            d = p[self._both] - last
            cost = (d * d).sum(axis=1).tolist()
            for k, (lo, hi) in enumerate(self._spans):
                keep, cross = sum(cost[lo:hi]), sum(cost[n + lo : n + hi])
                swap = self._decide(k, cross <= SWAP_MARGIN * keep, t)
                self.swapped[k] = swap
                if swap:
                    p[self._both[lo:hi]] = p[self._both[n + lo : n + hi]]
        self._last = p[self._twice]
        self._last_t = t
        return p

    def _decide(self, k: int, crossed: bool, t: float) -> bool:
        """Whether pair ``k`` is swapped back at time ``t``, given that its labels as sent
        crossed (sit nearer the last output's other side)."""
        believed = self._believed_at[k]
        if believed is not None and t - believed > self._max_swap:
            self._believed_at[k] = believed = None
        if not crossed:
            self._run_start[k] = None
            return False
        if believed is not None:  # the sender's return after a run that ran out
            self._believed_at[k] = None
            return False
        start = self._run_start[k]
        if start is None:
            self._run_start[k] = t
            return True
        if t - start < self._max_swap:
            return True
        self._run_start[k] = None
        self._believed_at[k] = t
        return False
