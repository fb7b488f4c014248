"""The playback clock of a recorded trajectory: which frame to show after some wall time.

Plain Python (no viser): the page's play thread calls :meth:`Timeline.advance` with the wall
time since its last tick; the slider and the scene follow :attr:`Timeline.frame`. Playback
loops at the end, so a short clip can be watched over and over without touching the page.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

SPEEDS: tuple[float, ...] = (0.1, 0.25, 0.5, 1.0, 2.0)


@dataclass
class Timeline:
    """``num_frames`` frames at ``fps``; frame k is at ``t0 + k / fps`` seconds."""

    num_frames: int
    fps: float
    t0: float = 0.0
    speed: float = 1.0
    playing: bool = True
    _position: float = 0.0  # fractional frame, so slow speeds still advance

    def __post_init__(self) -> None:
        if self.num_frames < 1:
            raise ValueError(f"a timeline needs at least one frame, got {self.num_frames}")
        if not (math.isfinite(self.fps) and self.fps > 0.0):
            raise ValueError(f"fps must be positive, got {self.fps}")

    @property
    def frame(self) -> int:
        return min(int(self._position), self.num_frames - 1)

    @property
    def time_s(self) -> float:
        return self.t0 + self.frame / self.fps

    def seek(self, frame: int) -> int:
        """Jump to ``frame`` (clamped to the clip); returns the frame shown."""
        self._position = float(min(max(frame, 0), self.num_frames - 1))
        return self.frame

    def advance(self, wall_s: float) -> int:
        """Move on by ``wall_s`` seconds of wall time at ``speed`` when playing; wrap at the
        end. Returns the frame shown."""
        if self.playing and wall_s > 0.0:
            self._position = (self._position + wall_s * self.speed * self.fps) % self.num_frames
        return self.frame
