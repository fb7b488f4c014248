"""Where an input frame's latency goes, stage by stage, from its arrival to the command sent.

Counted once per input frame, at the tick that first uses it (as LiveStats' latency):

- ``wait for tick``: from the frame's arrival (the source thread's stamp) to the start of the
  tick that picks it up — up to one control period by design;
- ``poll + interpolate``: draining the source and sampling the interpolated pose;
- ``retarget step``: network and optimizer;
- ``safety clamp``: joint-limit and velocity clamps;
- ``backend send``: packet build and write to the port (the bytes then take the write's wire
  time, ``robot_retarget.hardware.benchmark.cycle_bytes``);
- ``total``: arrival → the command handed to the port.
"""

from __future__ import annotations

from collections import deque

import numpy as np

STAGES = (
    "wait for tick",
    "poll + interpolate",
    "retarget step",
    "safety clamp",
    "backend send",
    "total",
)


class LatencyBudget:
    """Rolling windows (the last ``window`` input frames) of each stage's duration."""

    def __init__(self, window: int = 16384) -> None:
        self.samples: dict[str, deque[float]] = {s: deque(maxlen=window) for s in STAGES}

    def add(
        self,
        recv_s: float,
        tick_s: float,
        sampled_s: float,
        stepped_s: float,
        clamped_s: float,
        sent_s: float,
    ) -> None:
        """One input frame: its arrival and the loop's marks of the tick that first used it."""
        # A frame that arrived while the tick was polling waited for nothing.
        start = max(recv_s, tick_s)
        for stage, seconds in zip(
            STAGES,
            (
                start - recv_s,
                sampled_s - start,
                stepped_s - sampled_s,
                clamped_s - stepped_s,
                sent_s - clamped_s,
                sent_s - recv_s,
            ),
            strict=True,
        ):
            self.samples[stage].append(seconds)

    @property
    def frames(self) -> int:
        return len(self.samples["total"])

    def percentiles_ms(self, stage: str) -> tuple[float, float]:
        """(median, p99) of ``stage`` in ms; NaN before the first frame."""
        values = self.samples[stage]
        if not values:
            return float("nan"), float("nan")
        ms = np.fromiter(values, dtype=np.float64) * 1e3
        return float(np.median(ms)), float(np.percentile(ms, 99))

    def report(self) -> str:
        """A table, one line per stage, for the end of ``stream``."""
        if not self.frames:
            return "latency budget per input frame: no input frame arrived"
        lines = [f"latency budget per input frame ({self.frames} frames): median / p99 ms"]
        for stage in STAGES:
            median, p99 = self.percentiles_ms(stage)
            lines.append(f"  {stage:<20} {median:8.3f} {p99:8.3f}")
        return "\n".join(lines)
