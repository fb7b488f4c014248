"""One training batch for the retargeting models (what a dataset yields, what a step eats)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import torch

Tensor = torch.Tensor


@dataclass(frozen=True)
class RetargetBatch:
    """Windows of source motion, each with a target skeleton to retarget onto.

    ``same_skeleton`` (B,) bool marks samples whose target skeleton *is* the source's (NKN then
    uses its square loss instead of the adversarial one; the papers draw B = A with p = 0.5).
    ``real_*`` is a motion performed by each sample's target skeleton (its offsets are
    ``tgt_offsets``): NKN's discriminator learns the target's motion distribution from it.
    PMnet needs no real target motion (its discriminator compares scale-normalised mean-point
    trajectories with the source's).
    """

    src_local_quats: Tensor  # (B, T, J, 4) unit, root entry = global root orientation
    src_root_pos: Tensor  # (B, T, 3) m
    src_offsets: Tensor  # (B, J, 3) m
    tgt_offsets: Tensor  # (B, J, 3) m
    same_skeleton: Tensor  # (B,) bool
    real_local_quats: Tensor | None = None  # (B, T, J, 4) on tgt_offsets
    real_root_pos: Tensor | None = None  # (B, T, 3)
    # The same windows on the files' own skeleton, one topology per batch (SAN's encoders):
    native_domain: str | None = None
    native_quats: Tensor | None = None  # (B, T, A − 1, 4), robot_retarget.motion.native_pose
    native_offsets: Tensor | None = None  # (B, A − 1, 3) m

    def __post_init__(self) -> None:
        if self.src_local_quats.ndim != 4:
            raise ValueError(
                f"src_local_quats must be (B, T, J, 4), got {tuple(self.src_local_quats.shape)}"
            )
        b, t, j, _ = self.src_local_quats.shape
        if t < 2:
            raise ValueError(f"training windows need at least 2 frames (velocities), got {t}")
        expected = {
            "src_root_pos": (self.src_root_pos, (b, t, 3)),
            "src_offsets": (self.src_offsets, (b, j, 3)),
            "tgt_offsets": (self.tgt_offsets, (b, j, 3)),
            "same_skeleton": (self.same_skeleton, (b,)),
        }
        if self.real_local_quats is not None or self.real_root_pos is not None:
            if self.real_local_quats is None or self.real_root_pos is None:
                raise ValueError("give both real_local_quats and real_root_pos, or neither")
            expected["real_local_quats"] = (self.real_local_quats, (b, t, j, 4))
            expected["real_root_pos"] = (self.real_root_pos, (b, t, 3))
        native = (self.native_domain, self.native_quats, self.native_offsets)
        if any(v is not None for v in native):
            if (
                self.native_domain is None
                or self.native_quats is None
                or self.native_offsets is None
            ):
                raise ValueError("give native_domain, native_quats and native_offsets, or none")
            a = self.native_quats.shape[2] if self.native_quats.ndim == 4 else -1
            expected["native_quats"] = (self.native_quats, (b, t, a, 4))
            expected["native_offsets"] = (self.native_offsets, (b, a, 3))
        for name, (value, shape) in expected.items():
            if tuple(value.shape) != shape:
                raise ValueError(f"{name} must have shape {shape}, got {tuple(value.shape)}")

    def to(self, device: torch.device | str) -> RetargetBatch:
        """The same batch with every tensor on ``device``."""
        moved: dict[str, Any] = {
            f.name: value.to(device)
            for f in fields(self)
            if isinstance(value := getattr(self, f.name), torch.Tensor)
        }
        return replace(self, **moved)
