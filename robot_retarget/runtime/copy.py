"""numpy twin of the copy baselines' online step (no torch on the live path).

The ``copy`` and ``copy-scaled`` models (:mod:`robot_retarget.nn.models.copy`) only pass the
rotations through and re-integrate the root; running them through torch costs ~0.35 ms per
frame in tensor-op overhead. :class:`FastCopyRetargeter` does the same arithmetic with the numpy
``FeatureStream`` (robot_retarget.runtime.frame.FrameStream: heading from the root's +X
column, heading-free root velocity, then optional height-ratio scaling, integration from the
source's first root position and heading, heading put back on the root rotation), so its
output equals :class:`robot_retarget.nn.inference.OnlineRetargeter`'s to rounding (tested).
"""

from __future__ import annotations

from typing import Protocol

import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.runtime.frame import FrameStream, check_frame, check_offsets
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.skeleton import Skeleton


class OnlineStep(Protocol):
    """What the live step needs from a network: per-frame ``step`` and ``reset``."""

    def reset(self) -> None: ...

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]: ...


def rest_height_m(offsets: FloatArray) -> float:
    """Vertical extent of a canonical skeleton's rest pose (``nn.features.skeleton_height``)."""
    pos = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets).rest_positions()
    return float(pos[:, 1].max() - pos[:, 1].min())


class FastCopyRetargeter:
    """Online ``copy`` / ``copy-scaled`` on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,).

    ``velocity_scale`` multiplies the root's x, y, z velocity: 1.0 for ``copy``, the
    target/source height ratio for ``copy-scaled`` (the RuntimeModel picks it).
    """

    def __init__(
        self, source_offsets: npt.ArrayLike, target_offsets: npt.ArrayLike, velocity_scale: float
    ) -> None:
        # Same errors as OnlineRetargeter, so callers see one behaviour whichever path runs.
        check_offsets("source_offsets", source_offsets)
        check_offsets("target_offsets", target_offsets)
        self.velocity_scale = float(velocity_scale)
        self._stream = FrameStream()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._stream.reset()

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → (22, 4), (3,): rotations copied, root re-integrated."""
        q, root = check_frame(local_quats, root_pos)  # a copy: the root entry is rewritten
        vel, dyaw = self._stream.push(q, root)  # q's root is heading-free from here
        out_pos, out_yaw = self._stream.integrate(vel * self.velocity_scale, dyaw)
        return self._stream.apply_heading(q, out_yaw), out_pos
