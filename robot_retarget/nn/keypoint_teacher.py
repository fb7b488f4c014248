"""A keypoint model's teacher (``train --model agnostic2d --distill-from CKPT …``): trained
keypoint models, typically ``convert``'s centred ensemble, whose averaged answer on each training
window becomes a second target for the model being trained (knowledge distillation).

Why: the centred models see the second after each frame and their average is the best lifting
the project has (validation windows 9.19° against the causal model's 9.77°). A causal model
cannot see that second, but the teacher's answer is a target with less of each window's
ambiguity left in it than the ground truth, which no 2D view decides: the student learns what
the teacher makes of the window instead of one draw of what the performer did.

The teacher runs on the same batch, whole windows, no gradients. A teacher that saw the
student's validation or excluded subjects, itself or through a run it came from, would leak them
into the student's numbers, so it is refused (robot_retarget.nn.keypoint_lineage), as is one
trained at another frame rate or named twice.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from robot_retarget.errors import ModelLoadError, RetargetError
from robot_retarget.nn.keypoint_lineage import check_lineage
from robot_retarget.nn.models.agnostic2d import Agnostic2D, rotation_6d_to_matrix
from robot_retarget.npz_errors import is_numpy_archive


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

    def __init__(
        self,
        models: Sequence[Agnostic2D],
        sources: Sequence[dict[str, str]],
        payloads: Sequence[dict[str, Any]] | None = None,
    ) -> None:
        """``models`` with their ``sources`` (file and sha256, for the student's metadata) and
        checkpoint contents ``payloads`` (for :meth:`check_subjects`)."""
        if not models:
            raise ValueError("a teacher needs at least one model")
        self.models = list(models)
        self.sources = [dict(s) for s in sources]
        self.payloads = [dict(p) for p in payloads] if payloads is not None else [{}] * len(models)
        for m in self.models:
            m.eval()
            for p in m.parameters():
                p.requires_grad_(False)

    @classmethod
    def load(cls, paths: Sequence[str | Path], *, fps: float) -> KeypointTeacher:
        """The keypoint checkpoints at ``paths`` (trained at ``fps``, each file once); which
        subjects they saw is checked by :meth:`check_subjects` once the run's split is known."""
        from robot_retarget.nn.agnostic2d_training import load_keypoint_checkpoint

        models: list[Agnostic2D] = []
        sources: list[dict[str, str]] = []
        payloads: list[dict[str, Any]] = []
        for path in paths:
            if is_numpy_archive(Path(path)):  # by content: a missing file is named as such
                raise TeacherError(
                    f"--distill-from {path} is a numpy runtime, which the training cannot run: "
                    f"pass its torch checkpoint, {Path(path).with_suffix('.pt')}"
                )
            try:
                model, payload = load_keypoint_checkpoint(path)
            except ModelLoadError as exc:
                raise TeacherError(
                    f"--distill-from {path}: {exc.reason}; pass a keypoint model's .pt written "
                    "by train --model agnostic2d"
                ) from None
            taught_fps = payload.get("metadata", {}).get("fps")
            if taught_fps is not None and abs(float(taught_fps) - fps) > 1e-9:
                raise TeacherError(
                    f"--distill-from {path} was trained at {taught_fps:g} fps and would see "
                    f"this run's {fps:g} fps windows at the wrong pace: pass --fps {taught_fps:g} "
                    "or a teacher trained at this rate"
                )
            digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
            twin = next((s["checkpoint"] for s in sources if s["checkpoint_sha256"] == digest), "")
            if twin:
                raise TeacherError(
                    f"--distill-from {path} is the same file as {twin}: it would count twice in "
                    "the average; pass each teacher once"
                )
            models.append(model)
            payloads.append(payload)
            sources.append({"checkpoint": str(path), "checkpoint_sha256": digest})
        return cls(models, sources, payloads)

    def check_subjects(
        self,
        *,
        train_subjects: Sequence[str],
        validation_subjects: Sequence[str],
        excluded_subjects: Sequence[str],
    ) -> None:
        """Refuse a teacher (:class:`~robot_retarget.nn.keypoint_lineage.LineageError`) that,
        through any run it came from, trained on the run's validation or excluded subjects or
        on subjects it does not train on, or was chosen on its excluded ones."""
        for source, payload in zip(self.sources, self.payloads, strict=True):
            check_lineage(
                "--distill-from",
                source["checkpoint"],
                payload,
                validation_subjects=validation_subjects,
                excluded_subjects=excluded_subjects,
                train_subjects=train_subjects,
            )

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
