"""Live statistics of the control loop: latency, jitter, late and dropped input frames.

- latency: input-to-command, from the arrival of the newest input frame a command used to the
  moment that command was handed to the backend (counted once per input frame);
- jitter: how late each tick started against its schedule;
- late frames: input frames that arrived after their play time (the loop held meanwhile);
- dropped frames: what the source refused (by reason); overruns (ticks the loop overran) are
  counted on their own.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from robot_retarget.sources.base import SourceStats


@dataclass(frozen=True)
class StatsSnapshot:
    ticks: int
    commands: int
    latency_median_ms: float
    latency_p99_ms: float
    jitter_median_ms: float
    jitter_p99_ms: float
    late_frames: int
    late_ticks: int
    dropped_frames: int
    overruns: int

    def line(self) -> str:
        latency = (
            "latency: no input yet"
            if math.isnan(self.latency_median_ms)
            else f"latency median {self.latency_median_ms:.2f} ms p99 {self.latency_p99_ms:.2f} ms"
        )
        return (
            f"{latency} | "
            f"jitter median {self.jitter_median_ms:.2f} ms p99 {self.jitter_p99_ms:.2f} ms | "
            f"late frames {self.late_frames} (held ticks {self.late_ticks}) | "
            f"dropped {self.dropped_frames} | overruns {self.overruns} | "
            f"{self.commands} commands"
        )


def _pct(values: deque[float], q: float) -> float:
    if not values:
        return float("nan")
    return float(np.percentile(np.fromiter(values, dtype=np.float64), q)) * 1e3


class LiveStats:
    """Rolling windows (the last ``window`` samples) plus totals."""

    def __init__(self, window: int = 4096) -> None:
        self.latency_s: deque[float] = deque(maxlen=window)
        self.jitter_s: deque[float] = deque(maxlen=window)
        self.ticks = 0
        self.commands = 0
        self.late_ticks = 0
        self.overruns = 0
        self.late_frames = 0

    def snapshot(self, source: SourceStats) -> StatsSnapshot:
        return StatsSnapshot(
            ticks=self.ticks,
            commands=self.commands,
            latency_median_ms=_pct(self.latency_s, 50),
            latency_p99_ms=_pct(self.latency_s, 99),
            jitter_median_ms=_pct(self.jitter_s, 50),
            jitter_p99_ms=_pct(self.jitter_s, 99),
            late_frames=self.late_frames,
            late_ticks=self.late_ticks,
            dropped_frames=source.dropped_total,
            overruns=self.overruns,
        )
