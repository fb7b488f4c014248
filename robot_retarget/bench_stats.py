"""Timing statistics shared by every benchmark (median and p99 of per-run durations), and the
argument types of their counts and durations, so a bad value is a usage error before any work."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

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


def stage_records(
    stages: Sequence[str], times: Mapping[str, Sequence[float]]
) -> list[dict[str, Any]]:
    """One record per stage, in ``stages`` order: median, p99 and mean ms of its durations
    in seconds, and the number of runs (the rows ``bench`` prints)."""
    records: list[dict[str, Any]] = []
    for name in stages:
        stats = TimingStats.from_seconds(times[name])
        records.append(
            {
                "stage": name,
                "median_ms": stats.median_ms,
                "p99_ms": stats.p99_ms,
                "mean_ms": stats.mean_ms,
                "runs": stats.runs,
            }
        )
    return records
