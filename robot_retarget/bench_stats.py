"""Timing statistics shared by every benchmark: median and p99 of per-run durations."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TimingStats:
    runs: int
    median_ms: float
    p99_ms: float
    mean_ms: float

    @classmethod
    def from_seconds(cls, durations_s: Sequence[float]) -> TimingStats:
        if len(durations_s) == 0:
            raise ValueError("no timings to summarise")
        ms = np.asarray(durations_s, dtype=np.float64) * 1e3
        return cls(
            runs=int(ms.size),
            median_ms=float(np.median(ms)),
            p99_ms=float(np.percentile(ms, 99)),
            mean_ms=float(ms.mean()),
        )
