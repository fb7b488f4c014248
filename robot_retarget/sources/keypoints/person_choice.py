"""Which person to follow when a pose estimator sees several.

The rule: on the first frame with anyone in view, the person with the largest box (of their
visible keypoints, the outermost tenth on each side left out) — usually the one nearest the
camera. After that, the person whose centre (the median of their visible keypoints) is nearest
the followed person's last centre, if it lies within half the diagonal of their largest box
in their last 5 frames; both centres
are taken over the keypoints seen in both frames (where at least two are), so a body that
comes into view below its head and shoulders is still the same person; if nobody does,
the frame counts as nobody seen (every point missing, never another person's points). After
``reacquire_frames`` such frames in a row (default 15, 0.5 s at 30 fps) the largest person is
chosen again.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray

REACQUIRE_FRAMES = 15


REACH_FRAMES = 5
"""The reach is half the largest diagonal of the followed person's boxes in this many of their
last frames."""

TRIM_PERCENT = 10.0
"""The box leaves out this share of the visible points on each side, and its centre is their
median: one wild point (an estimator's glitch reported at full confidence) moves neither, where
it would drag a plain bounding box's centre away and the person would be dropped."""


def _box(xy: FloatArray, valid: BoolArray) -> tuple[FloatArray, float, float] | None:
    """Centre (2,), area and diagonal of the visible points' box (:data:`TRIM_PERCENT`); None if
    fewer than 2 are seen."""
    pts = xy[valid]
    if len(pts) < 2:
        return None
    lo = np.percentile(pts, TRIM_PERCENT, axis=0)
    hi = np.percentile(pts, 100.0 - TRIM_PERCENT, axis=0)
    size = hi - lo
    centre: FloatArray = np.median(pts, axis=0)
    with np.errstate(over="ignore"):  # a glitch at 1e200 px: an infinite area, no warning
        return centre, float(size[0] * size[1]), float(np.hypot(size[0], size[1]))


class PersonTracker:
    """Applies the rule above one frame at a time: ``choose(people) → index or None``."""

    def __init__(self, reacquire_frames: int = REACQUIRE_FRAMES) -> None:
        self.reacquire_frames = reacquire_frames
        self.reset()

    def reset(self) -> None:
        self._centre: FloatArray | None = None
        self._diagonals: deque[float] = deque(maxlen=REACH_FRAMES)
        self._lost = 0
        self._last: tuple[FloatArray, BoolArray] | None = None  # the followed person's points

    def _distance(self, xy: FloatArray, valid: BoolArray, centre: FloatArray) -> float:
        """How far a candidate is from the followed person's last frame, over the points both
        show (a centre of other points would move as more of the body comes into view)."""
        assert self._centre is not None
        assert self._last is not None
        last_xy, last_valid = self._last
        both = valid & last_valid
        if int(both.sum()) >= 2:
            return float(np.linalg.norm(np.median(xy[both], 0) - np.median(last_xy[both], 0)))
        return float(np.linalg.norm(centre - self._centre))

    def choose(self, people: list[tuple[FloatArray, BoolArray]]) -> int | None:
        """``people``: (xy (K, 2), valid (K,)) per detected person; the followed one's index."""
        boxes = [_box(xy, v) for xy, v in people]
        candidates = [(i, b) for i, b in enumerate(boxes) if b is not None]
        if not candidates:
            self._miss()
            return None
        if self._centre is None:
            i, (centre, _area, diag) = max(candidates, key=lambda ib: ib[1][1])
            self._diagonals.clear()  # maybe another person: only their own boxes
        else:
            with np.errstate(over="ignore", invalid="ignore"):  # 1e200 px: far, not a warning
                dist = {i: self._distance(*people[i], b[0]) for i, b in candidates}
            i, (centre, _area, diag) = min(candidates, key=lambda ib: dist[ib[0]])
            # The followed person's largest box of the last frames sets the reach: one frame
            # of points collapsed onto a pixel (an estimator's failure) must not shrink it to
            # nothing for the next, and another person's box never widens it.
            if not dist[i] <= 0.5 * max(self._diagonals):
                self._miss()
                return None
        self._centre, self._lost = centre, 0
        self._diagonals.append(max(diag, 1e-6))
        xy, valid = people[i]
        self._last = (np.array(xy, dtype=np.float64), np.array(valid, dtype=bool))
        return i

    def _miss(self) -> None:
        self._lost += 1
        if self._lost >= self.reacquire_frames:
            self._centre = None
