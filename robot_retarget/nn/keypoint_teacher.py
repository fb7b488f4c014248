"""A keypoint model's teacher (``train --model agnostic2d --distill-from CKPT …``): trained
keypoint models, typically ``convert``'s centred ensemble, whose averaged answer on each training
window becomes a second target for the model being trained (knowledge distillation).

Why: the centred models see the second after each frame and their average is the best lifting
the project has (validation windows 9.19° against the causal model's 9.77°). A causal model
cannot see that second, but the teacher's answer is a target with less of each window's
ambiguity left in it than the ground truth, which no 2D view decides: the student learns what
the teacher makes of the window instead of one draw of what the performer did.

The teacher runs on the same batch, whole windows, no gradients. A teacher that trained on the
student's validation (or excluded) subjects would leak them into the student's selection, so it
is refused.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import torch

from robot_retarget.errors import RetargetError
from robot_retarget.nn.models.agnostic2d import Agnostic2D, rotation_6d_to_matrix


class TeacherError(RetargetError):
    """A ``--distill-from`` checkpoint cannot teach this run (names which and why)."""


@dataclass(frozen=True)
class TeacherAnswer:
    """The teacher models' rotation matrices averaged (N, T, 22, 3, 3): not a rotation in
    general, which the squared-distance loss does not need (its minimiser over rotations is the
    average's nearest rotation); and their global bone directions on the reference skeleton
    averaged (N, T, 21, 3)."""

    matrices: torch.Tensor
    directions: torch.Tensor


class KeypointTeacher:
    """Frozen keypoint models whose answers are averaged (see the module docstring)."""

    def __init__(self, models: Sequence[Agnostic2D], sources: Sequence[dict[str, str]]) -> None:
        if not models:
            raise ValueError("a teacher needs at least one model")
        self.models = list(models)
        self.sources = [dict(s) for s in sources]
        for m in self.models:
            m.eval()
            for p in m.parameters():
                p.requires_grad_(False)

    @classmethod
    def load(
        cls,
        paths: Sequence[str | Path],
        *,
        train_subjects: Sequence[str],
        held_out_subjects: Sequence[str],
    ) -> KeypointTeacher:
        """The checkpoints at ``paths``; each must have trained on none of ``held_out_subjects``
        (the student's validation and excluded subjects) and on no subject outside
        ``train_subjects``."""
        from robot_retarget.nn.agnostic2d_training import load_keypoint_checkpoint

        models: list[Agnostic2D] = []
        sources: list[dict[str, str]] = []
        for path in paths:
            model, payload = load_keypoint_checkpoint(path)
            taught = payload.get("metadata", {}).get("train_subjects")
            if taught is None:
                raise TeacherError(
                    f"--distill-from {path}: the checkpoint does not say which subjects it "
                    "trained on, so it may have seen this run's validation subjects; pass a "
                    "checkpoint written by train"
                )
            leaked = sorted(set(taught) & set(held_out_subjects))
            if leaked:
                raise TeacherError(
                    f"--distill-from {path} trained on {leaked}, which this run validates on or "
                    "excludes: its answers would leak them; pass a teacher trained without them"
                )
            unseen = sorted(set(taught) - set(train_subjects))
            if unseen:
                raise TeacherError(
                    f"--distill-from {path} trained on {unseen}, which this run does not train "
                    "on; pass a teacher trained on this run's training subjects"
                )
            models.append(model)
            sources.append(
                {
                    "checkpoint": str(path),
                    "checkpoint_sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest(),
                }
            )
        return cls(models, sources)

    def to(self, device: torch.device) -> KeypointTeacher:
        self.models = [m.to(device) for m in self.models]
        return self

    @torch.no_grad()
    def answer(self, features: torch.Tensor) -> TeacherAnswer:
        """The averaged answer on ``features`` (N, T, 51): each model on the whole window (a
        centred model looks ahead; a causal one pools its static codes over the window)."""
        from robot_retarget.nn.agnostic2d_training import bone_directions

        matrices = torch.zeros(())
        directions = torch.zeros(())
        for model in self.models:
            d6, _motion = model(features, causal=False)
            m = rotation_6d_to_matrix(d6)
            matrices = matrices + m
            directions = directions + bone_directions(m)
        n = len(self.models)
        return TeacherAnswer(matrices / n, directions / n)
