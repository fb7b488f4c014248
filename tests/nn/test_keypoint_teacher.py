"""Distilling keypoint models (``train --model agnostic2d --distill-from``): the teacher's answer
is its models' average, the loss blends truth and teacher by ``--distill-weight``, a teacher that
saw the run's validation subjects is refused, and the run records what taught it."""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import pytest
import torch

from robot_retarget.cli import train_cmd
from robot_retarget.nn.agnostic2d_training import (
    KeypointTrainConfig,
    KeypointTrainError,
    RenderedBatch,
    bone_directions,
    load_keypoint_checkpoint,
    losses,
    quat_to_matrix,
)
from robot_retarget.nn.keypoint_teacher import KeypointTeacher, TeacherAnswer, TeacherError
from robot_retarget.nn.models.agnostic2d import Agnostic2D, rotation_6d_to_matrix

_TINY = {"channels": 8, "static_hidden": 8, "head_hidden": 8}


def _batch(seed: int = 0, windows: int = 4, frames: int = 12) -> RenderedBatch:
    g = torch.Generator().manual_seed(seed)
    q = torch.randn(windows, frames, 22, 4, generator=g)
    return RenderedBatch(
        torch.randn(windows, frames, 51, generator=g), q / q.norm(dim=-1, keepdim=True)
    )


def _cfg(weight: float) -> KeypointTrainConfig:
    return KeypointTrainConfig(data_dir="-", out_dir="-", limb_weight=2.0, distill_weight=weight)


def test_the_loss_blends_truth_and_teacher_by_the_distill_weight() -> None:
    """A teacher that answers the truth changes nothing; otherwise the total is linear in the
    weight, the truth's terms at 0 and the teacher's at 1, and the logged rotation, direction
    and limb terms stay the truth's."""
    torch.manual_seed(0)
    model = Agnostic2D(**_TINY).eval()  # no dropout: the same answer every call
    batch = _batch()
    target = quat_to_matrix(batch.targets)
    plain = losses(model, batch, True, _cfg(0.5))
    as_truth = losses(model, batch, True, _cfg(0.5), TeacherAnswer(target, bone_directions(target)))
    assert torch.allclose(as_truth["total"], plain["total"], atol=1e-6)
    assert torch.allclose(as_truth["teacher_rotation"], plain["rotation"], atol=1e-6)
    other = rotation_6d_to_matrix(torch.randn(*target.shape[:-2], 6))
    teacher = TeacherAnswer(other, bone_directions(other))
    totals = {w: losses(model, batch, True, _cfg(w), teacher) for w in (0.0, 0.3, 1.0)}
    assert torch.allclose(totals[0.0]["total"], plain["total"], atol=1e-6)
    blend = 0.7 * totals[0.0]["total"] + 0.3 * totals[1.0]["total"]
    assert torch.allclose(totals[0.3]["total"], blend, atol=1e-5)
    assert not torch.allclose(totals[1.0]["total"], plain["total"], atol=1e-3)
    for name in ("rotation", "direction", "limbs"):
        assert torch.equal(totals[0.3][name], plain[name])


def test_the_teacher_averages_its_models_on_whole_windows() -> None:
    """Two copies of one model teach what one does; the answer needs no gradient; a causal
    model teaches with its static codes pooled over the window."""
    torch.manual_seed(1)
    model = Agnostic2D(**_TINY)
    twin = Agnostic2D(**_TINY)
    twin.load_state_dict(model.state_dict())
    features = _batch().features
    source = {"checkpoint": "x", "checkpoint_sha256": "0"}
    one = KeypointTeacher([model], [source]).answer(features)
    two = KeypointTeacher([model, twin], [source, source]).answer(features)
    assert torch.allclose(one.matrices, two.matrices, atol=1e-6)
    assert torch.allclose(one.directions, two.directions, atol=1e-6)
    assert not one.matrices.requires_grad
    with torch.no_grad():
        whole = rotation_6d_to_matrix(model.eval()(features, causal=False)[0])
    assert torch.allclose(one.matrices, whole, atol=1e-6)
    with pytest.raises(ValueError, match="at least one model"):
        KeypointTeacher([], [])


def test_a_distill_weight_outside_zero_to_one_is_refused() -> None:
    with pytest.raises(KeypointTrainError, match=r"--distill-weight 1.5 is not in \[0, 1\]"):
        _cfg(1.5)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    train_cmd.configure(parser)
    return parser


def _tiny_args(data: Path, out: Path, *extra: str) -> list[str]:
    return ["--model", "agnostic2d", "--data", str(data / "mocap"), "--out", str(out),
            "--steps", "2", "--batch-size", "2", "--window", "32", "--val-every", "2",
            "--max-frames", "240", "--quiet", *(f"--model-config={k}={v}" for k, v in
            _TINY.items()), *extra]  # fmt: skip


@pytest.mark.data
def test_a_distilled_run_records_its_teacher_and_refuses_one_that_saw_its_validation(
    shared_data_dir: Path, tmp_path: Path
) -> None:
    """The student's checkpoint names each teacher file with its sha256 and the weight, and
    its log the teacher's terms; a teacher trained on the student's validation subjects is
    refused before the run writes a file, as are a weight without a teacher and a teacher for
    another model."""
    parser = _parser()
    teacher = tmp_path / "teacher"
    assert train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, teacher))) == 0
    student = tmp_path / "student"
    args = _tiny_args(shared_data_dir, student, "--distill-from", str(teacher / "best.pt"),
                      "--distill-weight", "0.8")  # fmt: skip
    assert train_cmd.run(parser.parse_args(args)) == 0
    _model, payload = load_keypoint_checkpoint(student / "best.pt")
    meta = payload["metadata"]
    digest = hashlib.sha256((teacher / "best.pt").read_bytes()).hexdigest()
    assert meta["distilled_from"] == [
        {"checkpoint": str(teacher / "best.pt"), "checkpoint_sha256": digest}
    ]
    assert meta["distill_weight"] == 0.8
    assert json.loads((student / "config.json").read_text())["distill_from"] == [
        str(teacher / "best.pt")
    ]
    assert "teacher_direction" in (student / "log.csv").read_text()

    leaky = tmp_path / "leaky"  # validates on 13, so trains on 06, 08 and 12
    assert train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, leaky, "--val-subjects",
                                                      "13"))) == 0  # fmt: skip
    refused = tmp_path / "refused"
    with pytest.raises(TeacherError, match=r"trained on \['06', '08', '12'\], which this run"):
        train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, refused, "--distill-from",
                                                   str(leaky / "best.pt"))))  # fmt: skip
    assert not any(refused.iterdir())
    with pytest.raises(train_cmd.TrainArgumentError, match="no --distill-from names one"):
        train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, tmp_path / "w",
                                                   "--distill-weight", "0.7")))  # fmt: skip
    with pytest.raises(train_cmd.TrainArgumentError, match="--distill-from and --distill-weight"):
        train_cmd.run(parser.parse_args(["--model", "residual", "--out", str(tmp_path / "r"),
                                         "--distill-from", str(teacher / "best.pt")]))  # fmt: skip
