"""Where a control tick's time goes: per-stage durations, summed per tick.

The backend and the benchmark call :meth:`StageTimer.lap` after each stage; a stage met twice
in one tick (one Sync Write per bus) adds up. :meth:`StageTimer.commit` closes the tick.
"""

from __future__ import annotations

import time


class StageTimer:
    def __init__(self) -> None:
        self.samples: dict[str, list[float]] = {}  # stage → seconds per tick
        self._tick: dict[str, float] = {}
        self._t = time.perf_counter()

    def start(self) -> None:
        """A tick begins now."""
        self._tick.clear()
        self._t = time.perf_counter()

    def lap(self, stage: str) -> None:
        """``stage`` ran from the previous lap (or start) until now."""
        now = time.perf_counter()
        self._tick[stage] = self._tick.get(stage, 0.0) + (now - self._t)
        self._t = now

    def commit(self) -> None:
        """The tick is over: keep its stage times."""
        for stage, seconds in self._tick.items():
            self.samples.setdefault(stage, []).append(seconds)
        self._tick.clear()
