"""The papers' baselines: copy the source's rotations and root velocities to the target.

``copy`` is NKN's and PMnet's "Copy input quaternions and velocities": local rotations as
they are (the target's FK then respects its own bone lengths) and root velocities unchanged.
``copy-scaled`` also scales the root's x, y, z velocities by the target/source height ratio
(rest-pose vertical extent), so a small robot does not take a grown-up's stride.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import torch

from robot_retarget.nn.features import FrameFeatures, MotionFeatures, skeleton_height
from robot_retarget.nn.models.base import Prediction, RetargetModel

if TYPE_CHECKING:
    from robot_retarget.runtime.model import RuntimeModel

Tensor = torch.Tensor


class CopyModel(RetargetModel):
    """Copy rotations and root velocities (no parameters, no state)."""

    name = "copy"
    trainable = False

    def config(self) -> dict[str, Any]:
        return {}

    def runtime(self) -> RuntimeModel | None:
        if type(self) not in (CopyModel, CopyScaledModel):
            return None  # a subclass may change what is copied: it keeps the torch step
        from robot_retarget.runtime.model import RuntimeModel

        return RuntimeModel(name=self.name, architecture=self.name)

    def velocity_scale(self, src_offsets: Tensor, tgt_offsets: Tensor) -> Tensor | None:
        """Factor (B,) on the root's x, y, z velocity; None keeps it."""
        return None

    def _scaled(self, root_vel: Tensor, src_offsets: Tensor, tgt_offsets: Tensor) -> Tensor:
        scale = self.velocity_scale(src_offsets, tgt_offsets)
        if scale is None:
            return root_vel
        shape = (-1,) + (1,) * (root_vel.ndim - 2)
        return torch.cat([root_vel[..., :3] * scale.view((*shape, 1)), root_vel[..., 3:]], -1)

    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        return Prediction(
            local_quats=src.local_quats,
            root_vel=self._scaled(src.root_vel, src_offsets, tgt_offsets),
        )

    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        return src.local_quats, self._scaled(src.root_vel, src_offsets, tgt_offsets)


class CopyScaledModel(CopyModel):
    """Copy rotations; scale root velocities by the target/source height ratio."""

    name = "copy-scaled"

    def velocity_scale(self, src_offsets: Tensor, tgt_offsets: Tensor) -> Tensor | None:
        return skeleton_height(tgt_offsets, self.parents) / skeleton_height(
            src_offsets, self.parents
        )
