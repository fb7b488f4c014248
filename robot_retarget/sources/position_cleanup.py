"""What a live positions receiver does to a frame before solving it to rotations.

Two tracker faults are undone frame by frame, each by evidence no real measurement produces
(:mod:`.frozen_joints`, :mod:`.limb_swaps`): joints held in place while occluded are carried
along with their parents, then left and right limbs swapped by the estimator are swapped back.
Everything else (jitter, bone-length noise, latency) passes unchanged: telling it from motion
takes a filter with lag (``stream --one-euro``), not a rule.
"""

from __future__ import annotations

import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.canonical import ARM_CHAINS, CANONICAL_PARENTS, LEG_CHAINS
from robot_retarget.sources.frozen_joints import FrozenJointFill
from robot_retarget.sources.limb_swaps import LimbSwapFix


class PositionCleanup:
    """``cleanup(positions (22, 3), t_s)`` → the canonical joints with tracker faults undone;
    ``t_s`` is the sender's timestamp. Frames must come in the order they are accepted; one
    whose timestamp goes back starts a new stream (a sender restart)."""

    def __init__(self) -> None:
        self.frozen = FrozenJointFill(CANONICAL_PARENTS)
        self.swaps = LimbSwapFix((ARM_CHAINS, LEG_CHAINS))
        self._last_t: float | None = None

    def reset(self) -> None:
        """A new stream: nothing carried over from the last one."""
        self.frozen.reset()
        self.swaps.reset()
        self._last_t = None

    def __call__(self, positions: npt.ArrayLike, t_s: float) -> FloatArray:
        t = float(t_s)
        if self._last_t is not None and not t > self._last_t:
            self.reset()
        self._last_t = t
        # Frozen joints first: they are told by a bitwise repeat of the labels as sent.
        return self.swaps(self.frozen(positions), t)
