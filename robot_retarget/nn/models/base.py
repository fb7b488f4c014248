"""The interface every retargeting model implements, clip-wise and frame-by-frame.

A model maps a source motion (local rotations, root positions, rest offsets of the performer)
and a target skeleton (rest offsets, e.g. a robot's canonical skeleton) to rotations and root
motion for the target. Internally every model works on the papers' features
(:mod:`robot_retarget.nn.features`): it predicts heading-free local rotations and a root
velocity per frame; this base class integrates the velocities from the source's first root
position and heading and puts the heading back on the root rotation.

Two paths give the same numbers (up to float rounding) for the models that are causal:

- ``model(src_local_quats, src_root_pos, src_offsets, tgt_offsets)`` on whole clips (training,
  offline retargeting);
- ``model.reset()`` then ``model.step(...)`` once per incoming frame (live retargeting).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import torch
from torch import nn

from robot_retarget.nn.features import (
    FeatureStream,
    FrameFeatures,
    MotionFeatures,
    apply_heading,
    compute_features,
    integrate_root,
    local_positions,
)
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS

if TYPE_CHECKING:
    from robot_retarget.runtime.model import RuntimeModel

Tensor = torch.Tensor


@dataclass(frozen=True)
class Prediction:
    """What a model predicts from features: heading-free rotations and root velocities.

    ``local_pos`` is FK of ``local_quats`` on the target skeleton when the model computed it
    anyway (NKN's FK layer); None lets the caller compute it. ``extras`` carries what a model's
    losses need (PMnet: q_A, φ_A).
    """

    local_quats: Tensor  # (B, T, J, 4) unit, root entry heading-free
    root_vel: Tensor  # (B, T, 4)
    local_pos: Tensor | None = None  # (B, T, J, 3)
    extras: Mapping[str, Tensor] = field(default_factory=dict)


@dataclass(frozen=True)
class RetargetOutput:
    """A retargeted motion for the target skeleton.

    ``local_quats`` (B, T, J, 4) unit quaternions, the root entry the global root orientation;
    ``root_pos`` (B, T, 3) metres, integrated from the predicted velocities starting at the
    source's first root position and heading. ``features`` is the same motion in the papers'
    representation (local pose on the target skeleton, root velocities, heading-free rotations,
    integrated heading) for the losses; ``extras`` as in :class:`Prediction`.
    """

    local_quats: Tensor
    root_pos: Tensor
    features: MotionFeatures
    extras: Mapping[str, Tensor] = field(default_factory=dict)


@dataclass(frozen=True)
class RetargetFrame:
    """One retargeted frame: ``local_quats`` (B, J, 4), ``root_pos`` (B, 3)."""

    local_quats: Tensor
    root_pos: Tensor


class RetargetModel(nn.Module, ABC):
    """Base of every retargeting model (see the module docstring).

    Subclasses implement :meth:`retarget` (clips of features), :meth:`step_features` (one frame
    of features, using state reset by :meth:`reset_state`) and :meth:`config` (the constructor
    arguments, stored in checkpoints).
    """

    name: ClassVar[str]
    trainable: ClassVar[bool] = True

    def __init__(self) -> None:
        super().__init__()
        # Every model works on the canonical human joint set (robots included, via their
        # canonical skeletons).
        self.num_joints = len(CANONICAL_JOINTS)
        self.parents = CANONICAL_PARENTS
        self._stream = FeatureStream(self.parents)

    def runtime(self) -> RuntimeModel | None:
        """This model's numpy runtime (robot_retarget.runtime) for the live path, or None when
        its architecture has none (the live path then steps it through torch)."""
        return None

    @abstractmethod
    def config(self) -> dict[str, Any]:
        """Constructor keyword arguments that rebuild this model (JSON-compatible values)."""

    @classmethod
    def upgrade_config(cls, config: dict[str, Any]) -> dict[str, Any]:
        """A stored :meth:`config` made current: a key added since then gets the value that
        rebuilds the model the checkpoint was trained as (not the new default)."""
        return config

    @abstractmethod
    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        """Predict the target's heading-free rotations and root velocities for whole clips."""

    @abstractmethod
    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        """One frame: heading-free rotations (B, J, 4) and root velocity (B, 4)."""

    def reset_state(self) -> None:
        """Clear the model's own online state (hidden states, buffers)."""

    def fit_normalization(self, features: MotionFeatures, offsets: Tensor) -> None:
        """Fit input statistics from training features (models without inputs ignore it)."""

    def forward(
        self,
        src_local_quats: Tensor,
        src_root_pos: Tensor,
        src_offsets: Tensor,
        tgt_offsets: Tensor,
    ) -> RetargetOutput:
        """Retarget clips: (B, T, J, 4), (B, T, 3), (B, J, 3), (B, J, 3) → RetargetOutput.

        Inputs are cast to the model's dtype (float32 for trained models).
        """
        src_local_quats, src_root_pos, src_offsets, tgt_offsets = self._cast(
            src_local_quats, src_root_pos, src_offsets, tgt_offsets
        )
        src = compute_features(src_local_quats, src_root_pos, src_offsets, self.parents)
        return self.retarget_features(src, src_root_pos[:, 0], src_offsets, tgt_offsets)

    def retarget_features(
        self,
        src: MotionFeatures,
        init_root_pos: Tensor,
        src_offsets: Tensor,
        tgt_offsets: Tensor,
    ) -> RetargetOutput:
        """Retarget features (e.g. another model pass's output, as NKN's cycle does)."""
        pred = self.retarget(src, src_offsets, tgt_offsets)
        return self.output(pred, init_root_pos, src.yaw[:, 0], tgt_offsets)

    def output(
        self, pred: Prediction, init_root_pos: Tensor, init_yaw: Tensor, tgt_offsets: Tensor
    ) -> RetargetOutput:
        """A prediction as a motion: root integrated from ``init_root_pos`` (B, 3) and heading
        ``init_yaw`` (B,), local pose by FK on ``tgt_offsets`` unless the model gave it."""
        local_pos = pred.local_pos
        if local_pos is None:
            local_pos = local_positions(pred.local_quats, tgt_offsets, self.parents)
        root_pos, yaw = integrate_root(pred.root_vel, init_root_pos, init_yaw)
        feats = MotionFeatures(
            local_pos=local_pos, root_vel=pred.root_vel, local_quats=pred.local_quats, yaw=yaw
        )
        return RetargetOutput(
            local_quats=apply_heading(pred.local_quats, yaw),
            root_pos=root_pos,
            features=feats,
            extras=pred.extras,
        )

    def _cast(self, *tensors: Tensor) -> tuple[Tensor, ...]:
        param = next(self.parameters(), None)
        if param is None:  # parameter-free baselines keep the caller's dtype
            return tensors
        return tuple(t if t.dtype == param.dtype else t.to(param.dtype) for t in tensors)

    def reset(self) -> None:
        """Start a new live sequence: the next :meth:`step` is frame 0."""
        self._stream.reset()
        self.reset_state()

    def step(
        self,
        src_local_quats: Tensor,
        src_root_pos: Tensor,
        src_offsets: Tensor,
        tgt_offsets: Tensor,
    ) -> RetargetFrame:
        """Retarget one live frame: (B, J, 4), (B, 3), (B, J, 3), (B, J, 3) → RetargetFrame.

        Causal: uses only this and earlier frames. Call :meth:`reset` before a new sequence
        and run in ``eval()`` mode (dropout off) under ``torch.inference_mode()`` for speed.
        """
        src_local_quats, src_root_pos, src_offsets, tgt_offsets = self._cast(
            src_local_quats, src_root_pos, src_offsets, tgt_offsets
        )
        frame = self._stream.push(src_local_quats, src_root_pos, src_offsets)
        quats, vel = self.step_features(frame, src_offsets, tgt_offsets)
        root_pos, yaw = self._stream.integrate(vel)
        return RetargetFrame(local_quats=apply_heading(quats, yaw), root_pos=root_pos)
