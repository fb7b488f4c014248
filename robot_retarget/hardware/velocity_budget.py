"""How far each joint may still move at its velocity limit in the time that really passed.

Command stamps are the caller's word; this is the clock's. Each joint's budget fills at its
velocity limit as the clock runs, up to ``depth_s`` seconds' worth, and every step spends from
it: commands sent faster than real time get only the time that passed, while a loop at its
rate, whose late tick is followed by an early one, keeps its full steps. The safety layer
clamps to it (three periods deep); the Dynamixel backend, used without one, refuses what goes
past its own (twice as deep).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robot_retarget.array_types import FloatArray


class VelocityBudget:
    """Per joint (``max_velocity`` (J,) rad/s), the travel left on ``clock`` (seconds)."""

    def __init__(
        self, max_velocity: FloatArray, depth_s: float, clock: Callable[[], float]
    ) -> None:
        self.max_velocity = max_velocity
        self.clock = clock
        self.resize(depth_s)

    def resize(self, depth_s: float) -> None:
        """Save up ``depth_s`` seconds' worth at most; the budget starts full."""
        self.cap = np.asarray(self.max_velocity * depth_s, dtype=np.float64)
        self.fill()

    def fill(self) -> None:
        """A fresh start (a new stream, after a move made at its own pace): full, now."""
        self.left = self.cap.copy()
        self._t = self.clock()

    def available(self) -> FloatArray:
        """(J,) rad each joint may move now: what was left, filled by the time since."""
        now = self.clock()
        self.left = np.minimum(self.left + self.max_velocity * max(now - self._t, 0.0), self.cap)
        self._t = now
        return self.left

    def spend(self, step: FloatArray) -> None:
        """Take a step (J,) rad of |travel| out of the budget."""
        self.left = np.maximum(self.left - step, 0.0)
