"""The ramped start: the robot joins a motion that is already under way without a jump.

At a stream start (and on every return from the safe pose) the optimizer tracks the motion on
its own, from the first frame solved to its optimum, while the robot pursues that trajectory
from wherever it is. The pursuit's speed cap, per joint, is a fraction of its velocity limit:

1. ``fraction`` for at least ``min_s``, and until every joint is within ``catch_up_rad`` of
   the trajectory (or ``timeout_s`` has passed: a motion too fast to catch at that speed);
2. then rising linearly to the full velocity limit over ``rise_s``, so that a fast motion is
   caught without a step change of speed.

The ramp ends when the robot is on the trajectory (every joint within one step of it): from
then on the optimizer's history is the robot's, and tracking goes on with no seam. Should the
pursuit still not have caught up ``timeout_s`` after the rise began, it ends where it is
(``TIMED_OUT``) and the caller restarts the optimizer from the robot's pose.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray


class RampOutcome(str, enum.Enum):
    RAMPING = "ramping"
    ON_TRAJECTORY = "on-trajectory"
    TIMED_OUT = "timed-out"


@dataclass(frozen=True)
class RampSettings:
    fraction: float = 0.25  # of each joint's velocity limit, while the ramp speed holds
    min_s: float = 0.5  # the ramp speed holds at least this long
    catch_up_rad: float = 0.2  # then the speed rises once every joint is this close
    rise_s: float = 0.5  # from the ramp speed to the full velocity limit
    timeout_s: float = 3.0  # the longest the ramp speed holds, and the rise's grace period

    def __post_init__(self) -> None:
        if not 0.0 < self.fraction <= 1.0:
            raise ValueError(f"ramp_speed_fraction must be in (0, 1], got {self.fraction}")
        if not 0.0 <= self.min_s < self.timeout_s:
            raise ValueError(
                f"need 0 <= ramp_min_s < ramp_timeout_s, got {self.min_s} and {self.timeout_s}"
            )
        if not self.catch_up_rad > 0.0:
            raise ValueError(f"catch_up_rad must be positive, got {self.catch_up_rad}")
        if not self.rise_s >= 0.0:
            raise ValueError(f"ramp_rise_s must be >= 0, got {self.rise_s}")


def toward(q: FloatArray, goal: FloatArray, step: FloatArray) -> FloatArray:
    """``q`` moved toward ``goal`` by at most ``step`` per joint."""
    return q + np.clip(goal - q, -step, step)


class StartRamp:
    """One pursuit at a time: :meth:`begin`, then :meth:`advance` once per control tick.

    ``max_step`` (J,) rad is each joint's velocity limit times the control period.
    """

    def __init__(self, settings: RampSettings, max_step: FloatArray) -> None:
        self.settings = settings
        self.max_step = np.asarray(max_step, dtype=np.float64)
        self.slow_step = self.max_step * settings.fraction
        self.last_step = self.slow_step  # the step of the last advance()
        self._start = 0.0
        self._rise_start: float | None = None

    def begin(self, now_s: float) -> None:
        self._start = now_s
        self._rise_start = None

    def speed_fraction(self, now_s: float) -> float:
        """The pursuit's speed cap now, as a fraction of the velocity limits."""
        s = self.settings
        if self._rise_start is None:
            return s.fraction
        if s.rise_s == 0.0:
            return 1.0
        rising = min(1.0, (now_s - self._rise_start) / s.rise_s)
        return s.fraction + (1.0 - s.fraction) * rising

    def advance(
        self, now_s: float, q_robot: FloatArray, q_goal: FloatArray
    ) -> tuple[FloatArray, RampOutcome]:
        """The next command toward ``q_goal`` (the trajectory's command for this tick)."""
        s = self.settings
        elapsed = now_s - self._start
        gap = np.abs(q_goal - q_robot)
        close = float(gap.max()) <= s.catch_up_rad
        if self._rise_start is None and elapsed >= s.min_s and (close or elapsed >= s.timeout_s):
            self._rise_start = now_s
        step = self.max_step * self.speed_fraction(now_s)
        self.last_step = step  # the safety layer keeps the tick-rounded command within it
        q = toward(q_robot, q_goal, step)
        if elapsed >= s.min_s and bool(np.all(gap <= step)):
            return q, RampOutcome.ON_TRAJECTORY
        if self._rise_start is not None and now_s - self._rise_start >= s.timeout_s:
            return q, RampOutcome.TIMED_OUT
        return q, RampOutcome.RAMPING


def peak_speed_fraction(q: npt.ArrayLike, q_start: npt.ArrayLike, max_step: FloatArray) -> float:
    """The largest per-tick step of commands ``q`` (T, J) from ``q_start``, as a fraction of
    each joint's ``max_step`` (velocity limit × period): what a ramp check reads."""
    a = np.vstack([np.asarray(q_start, dtype=np.float64)[None], np.asarray(q, dtype=np.float64)])
    return float(np.max(np.abs(np.diff(a, axis=0)) / max_step, initial=0.0))
