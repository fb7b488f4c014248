"""An online network step that plays back outputs computed for the whole clip beforehand.

``convert`` of a BVH clip by a skeleton-aware model (SAN) reads the file on its own skeleton
through that skeleton's encoder, which the live step (canonical joints in) cannot: the network
runs once over the clip (causal, so frame t is what a frame-by-frame run would give at t), and
this step hands its frames to the optimizer one by one, as the live step would.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray


class PrecomputedStep:
    """``step`` returns frame t of ``quats`` (T, 22, 4) and ``root_pos`` (T, 3), t = 0, 1, …
    since the last :meth:`reset`; its inputs are the clip's own frames and are not read."""

    def __init__(self, quats: npt.ArrayLike, root_pos: npt.ArrayLike) -> None:
        self._quats = np.asarray(quats, dtype=np.float64)
        self._root = np.asarray(root_pos, dtype=np.float64)
        if self._quats.ndim != 3 or self._root.shape != (len(self._quats), 3):
            raise ValueError(
                f"need quats (T, J, 4) and root_pos (T, 3), got {self._quats.shape} and "
                f"{self._root.shape}"
            )
        self._t = 0

    def reset(self) -> None:
        self._t = 0

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        if self._t >= len(self._quats):
            raise ValueError(
                f"the network was run on {len(self._quats)} frames; frame {self._t} was asked for"
            )
        t = self._t
        self._t += 1
        return self._quats[t].copy(), self._root[t].copy()
