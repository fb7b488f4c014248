"""Keypoints no body could have produced, marked missing before the lifting.

A pose estimator sometimes reports one point far from the body at full confidence for a frame
or a few (a wrist on a chair leg, a knee on the other person). Passed on, one such frame sits in
the causal model's 2 s of context and in its running codes, and shook the whole robot for
seconds (a wrist thrown across the image for one frame every 0.5 s: three times the joint travel
of the clean stream, arms, legs and head at their speed limits). Two tests, against the
person's size in the image (:class:`BodyScale`):

- **bone length**: a shoulder or hip whose two trunk segments (the shoulder or hip line and
  its side of the torso) are both longer than :data:`SLACK` times their usual share of the body
  is missing; then a limb bone (shoulder → elbow … knee → ankle) that long marks its far end
  missing, unless its near end already is, or jumped further than the far end from where
  each was last (root outward: an elbow marked missing leaves its forearm to the second test);
- **speed** (once the body has been seen for :data:`SPEED_AFTER_S`): a point farther from where
  it was last accepted than :data:`MAX_SPEED` body sizes per second (plus :data:`MARGIN` for the
  estimator's noise) allows is missing — until it has
  been refused for :data:`REANCHOR_S`, when it is taken where it now is (an occlusion that
  ended elsewhere, or a first position that was the wrong one).

A coordinate beyond :data:`MAX_PIXELS` is always missing. Nothing else is marked before the
body's size is known (a frame with three of its segments in
view), the gate starts over when the sender's clock goes back (a restart), and the limits are
far from what the noise of a working estimator does: on the evaluation's
synthetic views (pixel jitter up to 1.5 % of the height, 1.5× at wrists and ankles) no point is
marked. The model sees a marked point as missing, as it was trained to (dropouts, occlusions).
"""

from __future__ import annotations

import math

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS, Coco

# Segments and their length in torso lengths (shoulder centre → hip centre) for an adult facing
# the camera (the reference skeleton's proportions, rounded).
_SEGMENTS: tuple[tuple[Coco, Coco, float], ...] = (
    (Coco.left_shoulder, Coco.right_shoulder, 0.7),
    (Coco.left_hip, Coco.right_hip, 0.45),
    (Coco.left_shoulder, Coco.left_elbow, 0.55),
    (Coco.right_shoulder, Coco.right_elbow, 0.55),
    (Coco.left_elbow, Coco.left_wrist, 0.5),
    (Coco.right_elbow, Coco.right_wrist, 0.5),
    (Coco.left_hip, Coco.left_knee, 0.8),
    (Coco.right_hip, Coco.right_knee, 0.8),
    (Coco.left_knee, Coco.left_ankle, 0.8),
    (Coco.right_knee, Coco.right_ankle, 0.8),
    (Coco.left_shoulder, Coco.left_hip, 1.0),
    (Coco.right_shoulder, Coco.right_hip, 1.0),
)

SLACK = 2.5
"""A limb bone may look this many times its usual share of the body before its far end is
refused (lens distortion, a short trunk bent toward the camera, proportions unlike the
reference's)."""
MAX_SPEED = 30.0
"""Body sizes (torso lengths) per second a point may move: 15 m/s for a 0.5 m torso, past a
boxer's punch."""
MARGIN = 0.3
"""Body sizes a point may be off where it was last accepted, whatever the time (the
estimator's noise)."""
REANCHOR_S = 0.25
"""A point refused this long is taken where it now is."""
SPEED_AFTER_S = 0.5
"""The speed test starts once the body has been seen this long: a clip's first frames may jump
(a calibration pose cut to the motion), and a person just seen has no track to keep."""
MAX_PIXELS = 1e5
"""A coordinate farther than this from the image origin is missing whatever else is known (no
camera image is that large; such a number is a sender's fault, and one would swamp the
camera fit's running sums)."""
SCALE_WINDOW_S = 2.0
"""The body's size is the 90th percentile of the per-frame estimates over this long: the
person seen at full size recently, not shrunk by a bend or a turn."""


_A = np.array([a for a, _b, _s in _SEGMENTS])
_B = np.array([b for _a, b, _s in _SEGMENTS])
_SHARE = np.array([share for _a, _b, share in _SEGMENTS])
_UPPER = np.array([2, 3, 6, 7])  # shoulder → elbow, hip → knee: their far ends first
_LOWER = np.array([4, 5, 8, 9])  # elbow → wrist, knee → ankle: unless the near end went
# A shoulder or hip is judged on the trunk before its limb is: it is the outlier when both of
# its trunk segments (the shoulder or hip line, and its side of the torso) are too long.
_TRUNK_POINTS = np.array([Coco.left_shoulder, Coco.right_shoulder, Coco.left_hip, Coco.right_hip])
_TRUNK_SEGMENTS = np.array([[0, 10], [0, 11], [1, 10], [1, 11]])
_SHOULDERS = np.array([Coco.left_shoulder, Coco.right_shoulder])
_HIPS = np.array([Coco.left_hip, Coco.right_hip])


class BodyScale:
    """The person's size in the image (torso lengths in pixels), from the frames so far."""

    def __init__(self, fps: float) -> None:
        self._window = np.zeros(max(1, round(SCALE_WINDOW_S * fps)))
        self._settled = max(1, round(SPEED_AFTER_S * fps))
        self.reset()

    def reset(self) -> None:
        self._count = 0  # estimates so far (the window holds the last len(window))
        self._pixels: float | None = None

    def add(self, lengths: FloatArray, seen: BoolArray, torso: float | None) -> None:
        """One frame's estimate from its segments' ``lengths`` (those ``seen``) and its torso
        length: the median of length / usual share (a glitch moves one or two of eleven: not
        the median)."""
        sizes = lengths[seen] / _SHARE[seen]
        if torso is not None:
            sizes = np.append(sizes, torso)
        if len(sizes) < 3:
            return
        self._window[self._count % len(self._window)] = float(np.median(sizes))
        self._count += 1
        n = min(self._count, len(self._window))
        k = int(0.9 * (n - 1))
        self._pixels = float(np.partition(self._window[:n], k)[k])

    @property
    def settled(self) -> bool:
        """Whether the body has been seen for :data:`SPEED_AFTER_S`."""
        return self._count >= self._settled

    @property
    def pixels(self) -> float | None:
        """The body size in pixels (the 90th-percentile-ranked estimate of the window), or None
        before any frame showed enough of it."""
        return self._pixels


class KeypointGate:
    """``step(xy (17, 2), valid (17,), t_s) → valid`` with the implausible points marked
    missing (module docstring); ``refused`` counts them. ``reset()`` for a new sender."""

    def __init__(self, fps: float = 30.0) -> None:
        self.scale = BodyScale(fps)
        self.refused = 0
        self.reset()

    def reset(self) -> None:
        self.scale.reset()
        self._t = -math.inf
        self._last = np.full((NUM_KEYPOINTS, 2), np.nan)
        self._last_t = np.full(NUM_KEYPOINTS, -math.inf)
        self._refused_since = np.full(NUM_KEYPOINTS, math.inf)

    def step(self, xy: FloatArray, valid: BoolArray, t_s: float) -> BoolArray:
        if t_s < self._t:  # the sender's clock went back: a restart, maybe another person
            self.reset()
        self._t = t_s
        p = np.where(valid[:, None], np.asarray(xy, dtype=np.float64), 0.0)
        ok = np.array(valid, dtype=bool) & np.isfinite(p).all(axis=1)
        wild = ok & (np.abs(p) > MAX_PIXELS).any(axis=1)
        if wild.any():
            self.refused += int(wild.sum())
            ok &= ~wild
            p[wild] = 0.0
        d = p[_A] - p[_B]
        lengths = np.hypot(d[:, 0], d[:, 1])  # hypot: no overflow at a glitch's 1e200 px
        seen = ok[_A] & ok[_B]
        size = self.scale.pixels
        if size is not None:
            refuse = np.zeros(NUM_KEYPOINTS, dtype=bool)
            jump = np.zeros(NUM_KEYPOINTS)  # the share of its allowed move each point made
            if self.scale.settled:
                step = p - self._last
                moved = np.hypot(step[:, 0], step[:, 1])  # NaN where never accepted: False
                allowed = (MAX_SPEED * (t_s - self._last_t) + MARGIN) * size
                waited = t_s - self._refused_since >= REANCHOR_S - 1e-9
                refuse = ok & (moved > allowed) & ~waited
                jump = np.nan_to_num(moved / allowed)
            long = seen & (lengths > SLACK * _SHARE * size)
            trunk_seen = seen[_TRUNK_SEGMENTS].sum(axis=1) == 2
            refuse[_TRUNK_POINTS[trunk_seen & long[_TRUNK_SEGMENTS].all(axis=1)]] = True
            for bones in (_UPPER, _LOWER):
                near, far = _A[bones], _B[bones]
                blamed = long[bones] & ~refuse[near]
                # The end that jumped further from where it was is the outlier (a shoulder
                # thrown up within the speed allowance); by default the far end.
                near_moved = jump[near] > jump[far]
                refuse[near[blamed & near_moved]] = True
                refuse[far[blamed & ~near_moved]] = True
            if refuse.any():
                first = refuse & ~np.isfinite(self._refused_since)
                self._refused_since[first] = t_s
                self.refused += int(refuse.sum())
                ok &= ~refuse
                seen = ok[_A] & ok[_B]
        self._last[ok] = p[ok]
        self._last_t[ok] = t_s
        self._refused_since[ok] = math.inf
        torso = None
        if ok[_SHOULDERS].all() and ok[_HIPS].all():
            mid = 0.5 * (p[_SHOULDERS].sum(axis=0) - p[_HIPS].sum(axis=0))
            torso = float(np.hypot(mid[0], mid[1]))
        self.scale.add(lengths, seen, torso)
        return ok


def gate_keypoints(xy: FloatArray, valid: BoolArray, fps: float) -> tuple[BoolArray, int]:
    """A whole sequence (T, 17, 2) / (T, 17) through :class:`KeypointGate` frame by frame, as
    ``stream`` runs it: the new ``valid`` and how many points were refused."""
    gate = KeypointGate(fps)
    out = np.stack([gate.step(xy[t], valid[t], t / fps) for t in range(len(xy))])
    return out, gate.refused
