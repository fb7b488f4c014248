"""What a live positions receiver does to a frame before solving it to rotations.

Two tracker faults are undone frame by frame, each by evidence no real measurement produces
(:mod:`.frozen_joints`, :mod:`.limb_swaps`): joints held in place while occluded are carried
along with their parents, then left and right limbs swapped by the estimator are swapped back.
Then the frame-to-frame jitter is filtered as strongly as the stream shows it
(:mod:`.jitter_filter`: on a clean stream it all but passes frames through). Bone-length noise
and latency pass unchanged.
"""

from __future__ import annotations

import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.canonical import ARM_CHAINS, CANONICAL_PARENTS, LEG_CHAINS
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.from_positions import PositionsToRotations
from robot_retarget.sources.frozen_joints import FrozenJointFill
from robot_retarget.sources.jitter_filter import JitterFilter
from robot_retarget.sources.limb_swaps import LimbSwapFix


class PositionCleanup:
    """``cleanup(positions (22, 3), t_s)`` → the canonical joints with tracker faults undone
    and jitter filtered; ``t_s`` is the sender's timestamp. Frames must come in the order they
    are accepted; one whose timestamp goes back starts a new stream (a sender restart)."""

    def __init__(self) -> None:
        self.frozen = FrozenJointFill(CANONICAL_PARENTS)
        self.swaps = LimbSwapFix((ARM_CHAINS, LEG_CHAINS))
        self.jitter = JitterFilter(CANONICAL_PARENTS)
        self._last_t: float | None = None

    def reset(self) -> None:
        """A new stream: nothing carried over from the last one."""
        self.frozen.reset()
        self.swaps.reset()
        self.jitter.reset()
        self._last_t = None

    def __call__(self, positions: npt.ArrayLike, t_s: float) -> FloatArray:
        t = float(t_s)
        if self._last_t is not None and not t > self._last_t:
            self.reset()
        self._last_t = t
        # Frozen joints first: they are told by a bitwise repeat of the labels as sent; the
        # jitter filter last, so that it never smooths across a swap or toward a frozen joint.
        return self.jitter(self.swaps(self.frozen(positions), t), t)


class LivePositions:
    """One live stream's position frames → (local rotations (22, 4), root (3,)) on
    ``skeleton``: the cleanup above (unless ``clean`` is False), then the solve. What the UDP
    source does with a position packet, and what the live replay does with a sender's frame."""

    def __init__(self, skeleton: Skeleton, *, clean: bool = True) -> None:
        self._solver = PositionsToRotations(skeleton)
        self._cleanup = PositionCleanup() if clean else None

    @property
    def cleans(self) -> bool:
        """Whether frames are cleaned (frozen joints, swapped limbs, jitter) before the solve."""
        return self._cleanup is not None

    def reset(self) -> None:
        """A new stream (the cleanup also starts over by itself when time goes back)."""
        if self._cleanup is not None:
            self._cleanup.reset()

    def __call__(self, positions: npt.ArrayLike, t_s: float) -> tuple[FloatArray, FloatArray]:
        """An accepted frame, in order, at the sender's time ``t_s``."""
        if self._cleanup is not None:
            positions = self._cleanup(positions, t_s)
        return self._solver.solve(positions)
