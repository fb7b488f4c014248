"""Input frames → the human pose at any control tick (slerp between frames, hold when late).

Input arrives at its own rate with jitter; the control loop ticks at a fixed rate. The
interpolator maps loop time to sender time with the smallest transit seen so far
(``offset = min(recv_s − t_s)``) plus a playout delay of one (measured) input period, so a
frame that arrives up to one period late is still interpolated to rather than jumped to. When
the play time passes the newest frame, the newest frame is held (a "late" tick). A timestamp
that goes backwards means the sender restarted: the buffer starts over; a frame more than
``resync_s`` behind the play time (a sender whose clock paused) re-anchors the clock mapping.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.sources.base import SourceFrame


@dataclass(frozen=True)
class Sample:
    """The pose to retarget at one tick. ``newest`` is the newest frame it used (latency is
    measured from its arrival); ``late`` is True when the input ran out and it is held."""

    local_quats: FloatArray
    root_pos: FloatArray
    play_t_s: float
    newest: SourceFrame
    late: bool


class FrameInterpolator:
    """``delay_s``: the playout delay; with ``adapt_periods`` set, the delay follows that many
    measured input periods (a running average of timestamp steps) instead, starting from
    ``delay_s``, so a sender slower or faster than announced is still interpolated."""

    def __init__(
        self, delay_s: float, max_frames: int = 64, adapt_periods: float | None = None
    ) -> None:
        if delay_s < 0.0:
            raise ValueError(f"delay_s must be ≥ 0, got {delay_s}")
        self.delay_s = delay_s
        self.adapt_periods = adapt_periods
        self._period_s = delay_s / adapt_periods if adapt_periods else 0.0
        self._frames: deque[SourceFrame] = deque(maxlen=max_frames)
        self._offset_s: float | None = None
        # Frames that arrived after a tick had wanted to play past them: the loop held. A
        # frame behind the play time on arrival but in the same poll as a newer one that
        # covers it (a sender faster than the loop) is not late: no tick missed it.
        self.late_frames = 0
        self._played_s = float("-inf")  # the last tick's play time
        self.restarts = 0
        self.resyncs = 0
        self.resync_s = 0.25  # a frame this far behind the play time re-anchors the clocks

    @property
    def empty(self) -> bool:
        return not self._frames

    @property
    def newest(self) -> SourceFrame | None:
        return self._frames[-1] if self._frames else None

    def clear(self) -> None:
        self._frames.clear()
        self._offset_s = None
        self._played_s = float("-inf")

    def play_time(self, now_s: float) -> float:
        if self._offset_s is None:
            return float("-inf")
        return now_s - self._offset_s - self.delay_s

    def push(self, frame: SourceFrame, now_s: float) -> None:
        if self._frames and frame.t_s <= self._frames[-1].t_s:
            self.clear()
            self.restarts += 1
        transit = frame.recv_s - frame.t_s
        if self._frames and frame.t_s < self._played_s:
            self.late_frames += 1
        if self._frames and frame.t_s < self.play_time(now_s) - self.resync_s:
            self._offset_s = transit  # the sender's clock paused or slowed: follow it
            self.resyncs += 1
        if self.adapt_periods and self._frames:
            step = frame.t_s - self._frames[-1].t_s
            self._period_s += 0.1 * (step - self._period_s)  # running average of the steps
            self.delay_s = self.adapt_periods * self._period_s
        if self._offset_s is None or transit < self._offset_s:
            self._offset_s = transit
        self._frames.append(frame)

    def sample(self, now_s: float) -> Sample | None:
        """The pose at loop time ``now_s``; None before the first frame."""
        if not self._frames:
            return None
        t = self.play_time(now_s)
        self._played_s = t
        frames = self._frames
        newest = frames[-1]
        if t >= newest.t_s:
            late = t > newest.t_s + 1e-9  # not a rounding hair past it
            return Sample(newest.local_quats, newest.root_pos, t, newest, late=late)
        while len(frames) >= 2 and frames[1].t_s <= t:
            frames.popleft()  # older frames are no longer needed
        a = frames[0]
        if t <= a.t_s or len(frames) == 1:
            return Sample(a.local_quats, a.root_pos, t, a, late=False)
        b = frames[1]
        w = (t - a.t_s) / (b.t_s - a.t_s)
        q = quat.slerp(a.local_quats, b.local_quats, w)
        root = a.root_pos + w * (b.root_pos - a.root_pos)
        return Sample(q, root, t, b, late=False)
