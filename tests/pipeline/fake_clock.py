"""Simulated time for tests of the control loop: no test here waits for the wall clock."""

from __future__ import annotations


class FakeClock:
    """``now`` for the loop and the simulator; ``sleep`` advances it instead of waiting."""

    def __init__(self, t0_s: float = 100.0) -> None:
        self.t = t0_s

    def now(self) -> float:
        return self.t

    def sleep(self, dt_s: float) -> None:
        self.t += max(dt_s, 0.0)
