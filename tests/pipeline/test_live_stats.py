from __future__ import annotations

import math

import pytest

from robot_retarget.pipeline.live_stats import LiveStats
from robot_retarget.sources.base import SourceStats


def test_snapshot_percentiles_and_counts() -> None:
    stats = LiveStats()
    stats.latency_s.extend([0.001 * k for k in range(1, 101)])
    stats.jitter_s.extend([0.0002] * 50)
    stats.ticks, stats.commands, stats.late_ticks, stats.overruns, stats.late_frames = (
        100, 90, 3, 2, 4,
    )  # fmt: skip
    src = SourceStats()
    src.drop("malformed")
    src.drop("nan")
    snap = stats.snapshot(src)
    assert snap.latency_median_ms == pytest.approx(50.5)
    assert snap.latency_p99_ms == pytest.approx(99.01)
    assert snap.jitter_median_ms == pytest.approx(0.2)
    assert snap.dropped_frames == 2  # the source's drops; the 2 overruns are their own count
    assert snap.late_frames == 4
    line = snap.line()
    assert "latency median 50.50 ms" in line
    assert "dropped 2 | overruns 2" in line


def test_empty_windows_give_nan() -> None:
    snap = LiveStats().snapshot(SourceStats())
    assert math.isnan(snap.latency_median_ms)
    assert snap.commands == 0


def test_source_summary_lists_reasons() -> None:
    src = SourceStats(received=5, accepted=3)
    src.drop("auth")
    src.drop("auth")
    assert src.summary() == "source: 5 received, 3 accepted, 2 dropped (auth 2)"
