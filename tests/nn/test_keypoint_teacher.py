"""Distilling keypoint models (``train --model agnostic2d --distill-from``): the teacher's answer
is its models' average, the loss blends truth and teacher by ``--distill-weight``, a teacher (or
an ``--init-from`` checkpoint) that saw the run's validation or test-fold subjects, itself or
through a run it came from, is refused, and the run records what taught it."""

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
from robot_retarget.nn.keypoint_lineage import LineageError, check_lineage, lineage
from robot_retarget.nn.keypoint_teacher import KeypointTeacher, TeacherAnswer, TeacherError
from robot_retarget.nn.models.agnostic2d import Agnostic2D, rotation_6d_to_matrix

_TINY = {"channels": 8, "static_hidden": 8, "head_hidden": 8}
CHECKPOINTS = Path(__file__).resolve().parents[2] / "robot_retarget" / "data" / "checkpoints"


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
    # Directions unrelated to the matrices: the loss must read the teacher's own.
    unrelated = rotation_6d_to_matrix(torch.randn(*target.shape[:-2], 6))
    teacher = TeacherAnswer(other, bone_directions(unrelated))
    totals = {w: losses(model, batch, True, _cfg(w), teacher) for w in (0.0, 0.3, 1.0)}
    assert torch.allclose(totals[0.0]["total"], plain["total"], atol=1e-6)
    blend = 0.7 * totals[0.0]["total"] + 0.3 * totals[1.0]["total"]
    assert torch.allclose(totals[0.3]["total"], blend, atol=1e-5)
    assert not torch.allclose(totals[1.0]["total"], plain["total"], atol=1e-3)
    rederived = TeacherAnswer(other, bone_directions(other))
    assert not torch.allclose(
        losses(model, batch, True, _cfg(1.0), rederived)["total"], totals[1.0]["total"], atol=1e-3
    )
    for name in ("rotation", "direction", "limbs"):
        assert torch.equal(totals[0.3][name], plain[name])


def test_the_teacher_averages_its_models_on_whole_windows() -> None:
    """Two models teach the mean of their matrices and the mean of their bone directions (not
    the directions of the mean); the answer needs no gradient; a causal model teaches with its
    static codes pooled over the window."""
    torch.manual_seed(1)
    a, b = Agnostic2D(**_TINY), Agnostic2D(**_TINY)
    features = _batch().features
    sources = [{"checkpoint": n, "checkpoint_sha256": n} for n in ("a", "b")]
    answer = KeypointTeacher([a, b], sources).answer(features)
    with torch.no_grad():
        ma, mb = (rotation_6d_to_matrix(m(features, causal=False)[0]) for m in (a, b))
    assert not torch.allclose(ma, mb, atol=1e-3)
    assert torch.allclose(answer.matrices, (ma + mb) / 2, atol=1e-6)
    mean_dirs = (bone_directions(ma) + bone_directions(mb)) / 2
    assert torch.allclose(answer.directions, mean_dirs, atol=1e-6)
    assert not torch.allclose(answer.directions, bone_directions(answer.matrices), atol=1e-3)
    assert not answer.matrices.requires_grad
    with pytest.raises(ValueError, match="at least one model"):
        KeypointTeacher([], [])


def test_a_distill_weight_outside_zero_to_one_is_refused() -> None:
    with pytest.raises(KeypointTrainError, match=r"--distill-weight 1.5 is not in \[0, 1\]"):
        _cfg(1.5)


def test_teacher_files_that_cannot_teach_are_refused_by_name(tmp_path: Path) -> None:
    """A numpy runtime, a missing or foreign file, a teacher trained at another rate and one
    named twice: each a one-line error naming --distill-from and what to pass instead."""
    shipped = CHECKPOINTS / "agnostic2d_clip.pt"
    cases = [
        ([CHECKPOINTS / "agnostic2d_clip.npz"], r"numpy runtime.*pass its torch checkpoint"),
        ([tmp_path / "gone.pt"], r"gone.pt: no such keypoint checkpoint; pass a keypoint"),
        ([tmp_path / "gone.npz"], r"gone.npz: no such keypoint checkpoint; pass a keypoint"),
        ([CHECKPOINTS / "default.pt"], r"not a robot-retarget-keypoint-model checkpoint; pass"),
        ([shipped, shipped], r"is the same file as .*pass each teacher once"),
    ]
    for paths, message in cases:
        with pytest.raises(TeacherError, match="--distill-from .*" + message):
            KeypointTeacher.load(paths, fps=30.0)
    with pytest.raises(TeacherError, match=r"trained at 30 fps .* pass --fps 30"):
        KeypointTeacher.load([shipped], fps=60.0)
    teacher = KeypointTeacher.load([shipped], fps=30.0)
    assert (
        teacher.sources[0]["checkpoint_sha256"] == hashlib.sha256(shipped.read_bytes()).hexdigest()
    )


def _checkpoint(path: Path, **metadata: object) -> Path:
    torch.save({"format": "robot-retarget-keypoint-model", "metadata": metadata}, path)
    return path


def test_a_checkpoint_is_refused_for_what_it_or_its_ancestors_saw(tmp_path: Path) -> None:
    """Subjects trained on by the checkpoint's run or any run it started from or learned from
    (followed through their files), or chosen on in any of them, are held against the run's
    split; an ancestor whose file is gone is named."""
    split = {"validation_subjects": ("06",), "excluded_subjects": ("13",)}
    clean = {"train_subjects": ["02", "05"], "validation_subjects": ["06"]}
    assert check_lineage("--init-from", "x", {"metadata": clean}, **split).trained == {"02", "05"}
    with pytest.raises(LineageError, match="does not say which subjects"):
        check_lineage("--init-from", "x", {"metadata": {}}, **split)
    with pytest.raises(LineageError, match=r"trained on \['06'\], which this run validates"):
        check_lineage("--init-from", "x", {"metadata": {"train_subjects": ["02", "06"]}}, **split)
    with pytest.raises(LineageError, match=r"chosen on \['13'\], which this run excludes"):
        check_lineage(
            "--init-from",
            "x",
            {"metadata": {"train_subjects": ["02"], "validation_subjects": ["13"]}},
            **split,
        )
    with pytest.raises(LineageError, match=r"trained on \['07'\], which this run does not"):
        check_lineage(
            "--distill-from",
            "x",
            {"metadata": {"train_subjects": ["02", "07"]}},
            **split,
            train_subjects=("02", "05"),
        )
    grandparent = _checkpoint(tmp_path / "gp.pt", train_subjects=["06"], validation_subjects=[])
    parent = _checkpoint(tmp_path / "p.pt", train_subjects=["02"], init_from=str(grandparent))
    child = {
        "metadata": {"train_subjects": ["02"], "distilled_from": [{"checkpoint": str(parent)}]}
    }
    with pytest.raises(LineageError, match=r"trained on \['06'\], which this run validates"):
        check_lineage("--distill-from", "child", child, **split)
    grandparent.unlink()
    seen = check_lineage("--distill-from", "child", child, **split)
    assert seen.unfollowed == (str(grandparent),)
    loop = _checkpoint(tmp_path / "loop.pt", train_subjects=["02"])
    _checkpoint(loop, train_subjects=["02"], init_from=str(loop))  # names itself: followed once
    assert lineage({"metadata": {"train_subjects": ["05"], "init_from": str(loop)}}).trained == {
        "02",
        "05",
    }


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
    for option in ("--distill-from", "--init-from"):
        with pytest.raises(LineageError, match=f"{option} .*" + r"trained on \['06', '08', '12'\]"):
            train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, refused, option,
                                                       str(leaky / "best.pt"))))  # fmt: skip
        assert not refused.exists()  # refused before it wrote a file: not even its folder
    # Chosen on 13 and trained without 06, 08, 12: refused only where 13 is the test fold.
    chosen = tmp_path / "chosen"
    assert train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, chosen, "--val-subjects",
                         "13", "--exclude-subjects", "06,08,12"))) == 0  # fmt: skip
    with pytest.raises(LineageError, match=r"chosen on \['13'\], which this run excludes"):
        train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, refused, "--distill-from",
                      str(chosen / "best.pt"), "--exclude-subjects", "13")))  # fmt: skip
    with pytest.raises(train_cmd.TrainArgumentError, match="no --distill-from names one"):
        train_cmd.run(parser.parse_args(_tiny_args(shared_data_dir, tmp_path / "w",
                                                   "--distill-weight", "0.7")))  # fmt: skip
    only_distill = r"^--distill-from is agnostic2d's; residual does not use it \(drop it"
    with pytest.raises(train_cmd.TrainArgumentError, match=only_distill):
        train_cmd.run(parser.parse_args(["--model", "residual", "--out", str(tmp_path / "r"),
                                         "--distill-from", str(teacher / "best.pt")]))  # fmt: skip
    two = r"^--speed-range and --distill-weight are agnostic2d's; pmnet does not use them"
    with pytest.raises(train_cmd.TrainArgumentError, match=two):
        train_cmd.run(parser.parse_args(["--model", "pmnet", "--out", str(tmp_path / "p"),
                                         "--distill-weight", "0.3",
                                         "--speed-range", "0.9,1.1"]))  # fmt: skip
    assert not (tmp_path / "r").exists()  # a refused run leaves no folder behind
