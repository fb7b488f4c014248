"""Cross-validation end to end on a tiny folder: the ten subjects of the default plan, each
made of the project's fixture clips, trained for two steps of a tiny residual model."""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import shutil
import statistics
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import torch

from robot_retarget.cli import train_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.evaluation.crossval import (
    BASELINES,
    CROSSVAL_JSON,
    PEEK_SUFFIX,
    CrossvalConfig,
    CrossvalError,
    crossval,
    format_report,
)
from robot_retarget.evaluation.folds import CONVERSIONS, DEFAULT_FOLDS, FoldError, FoldPlan
from robot_retarget.evaluation.runner import METRICS
from robot_retarget.nn.checkpoint import load_checkpoint
from robot_retarget.nn.dataset import DatasetError
from robot_retarget.nn.train import TrainProgress

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
# One clip per subject and two skeletons, as the two conversions of the real set.
CLIPS = {"j31": ("tiny_walk.bvh",), "j43": ("mixamo.bvh",)}


def make_tiny_set(root: Path, subjects: dict[str, str] | None = None) -> Path:
    """``root/<subject>/<subject>_<fixture>.bvh`` for each subject → conversion."""
    for subject, conversion in (subjects or dict(CONVERSIONS)).items():
        (root / subject).mkdir(parents=True)
        for name in CLIPS[conversion]:
            shutil.copy(FIXTURES / name, root / subject / f"{subject}_{name}")
    return root


def tiny_config(data: Path, out: Path, cache: Path, **overrides: Any) -> CrossvalConfig:
    settings: dict[str, Any] = {
        "models": ("residual",),
        "data_dir": str(data),
        "out_dir": str(out),
        "steps": 2,
        "batch_size": 4,
        "window_frames": 8,
        "train_robots": ("op3",),
        "val_every": 2,
        "checkpoint_every": 1,
        "model_config": {"hidden_size": 16, "num_layers": 1, "denoiser_hidden": 8},
        "cache_dir": str(cache),
        "lr": 1e-3,
    }
    return CrossvalConfig(**{**settings, **overrides})


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any], list[str]]:
    """One complete cross-validation: (out folder, report, log lines)."""
    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("cv")
    data = make_tiny_set(root / "mocap")
    lines: list[str] = []
    report = crossval(tiny_config(data, root / "out", root / "cache"), log=lines.append)
    return root / "out", report, lines


def test_report_structure(finished: tuple[Path, dict[str, Any], list[str]]) -> None:
    out, report, _ = finished
    assert json.loads((out / CROSSVAL_JSON).read_text()) == report
    assert report["folds"] == DEFAULT_FOLDS.to_json()
    assert len(report["data_hash"]) == 64
    assert set(report["git"]) == {"commit", "dirty"}
    assert report["settings"]["steps"] == 2
    assert [e["fold"] for e in report["cv"]] == ["cv-1", "cv-2", "cv-3"]
    for entry in [*report["cv"], report["test"]]:
        assert entry["clips"] == len(entry["subjects"])
        run = entry["runs"]["residual"]
        assert run["last_step"] == 2
        # The recorded command is a train command line that asks for this very run.
        parser = argparse.ArgumentParser()
        train_cmd.configure(parser)
        argv = shlex.split(run["train_command"])
        assert argv[:3] == ["python", "launch.py", "train"]
        args = parser.parse_args(argv[3:])
        stored = json.loads((Path(run["out"]) / "config.json").read_text())["config"]
        assert (args.model, args.out, args.steps) == ("residual", run["out"], 2)
        assert args.val_subjects.split(",") == (
            [""] if entry["fold"] == "test" else entry["subjects"]
        )
        assert args.exclude_subjects == "07,13" == ",".join(stored["exclude_subjects"])
        assert args.lr == stored["lr"]
        assert args.window == stored["window_frames"]
        for result in entry["scores"].values():
            assert set(result["metrics"]) == {k for k, _ in METRICS}
            assert result["clips"] == entry["clips"]
    assert set(report["cv"][0]["scores"]) == {*BASELINES, "residual", "residual" + PEEK_SUFFIX}
    # The final model has no validation, so no best.pt picked on anything: no peek row.
    assert set(report["test"]["scores"]) == {*BASELINES, "residual"}
    assert "best_step" not in report["test"]["runs"]["residual"]
    assert report["cv"][0]["runs"]["residual"]["best_step"] == 2


def test_test_fold_never_trained_or_validated_on(
    finished: tuple[Path, dict[str, Any], list[str]],
) -> None:
    out, report, _ = finished
    test = set(DEFAULT_FOLDS.test)
    assert set(report["test"]["subjects"]) == test
    runs = sorted((out / "residual").iterdir())
    assert [r.name for r in runs] == ["cv-1", "cv-2", "cv-3", "test"]
    for i, entry in enumerate(report["cv"]):
        assert entry["train_subjects"] == list(DEFAULT_FOLDS.train_subjects(i))
    for run in runs:
        config = json.loads((run / "config.json").read_text())["config"]
        assert config["exclude_subjects"] == sorted(test)
        for name in ("last.pt", "best.pt"):
            meta = load_checkpoint(run / name).metadata
            assert not set(meta["train_subjects"]) & test, (run, name)
            assert not set(meta["validation_subjects"]) & test, (run, name)
            assert not {f"subject:{s}" for s in test} & set(load_checkpoint(run / name).skeletons)
    final = load_checkpoint(out / "residual" / "test" / "last.pt").metadata
    assert final["train_subjects"] == list(DEFAULT_FOLDS.cv_subjects)
    assert final["validation_subjects"] == []


def test_summary_is_mean_and_spread_over_folds(
    finished: tuple[Path, dict[str, Any], list[str]],
) -> None:
    _, report, _ = finished
    for label in (*BASELINES, "residual"):
        for key in ("ee", "skate", "denoise"):
            values = [e["scores"][label]["metrics"][key] for e in report["cv"]]
            s = report["summary"]["cv"][label]["metrics"][key]
            assert s["mean"] == pytest.approx(statistics.fmean(values))
            assert s["std"] == pytest.approx(statistics.stdev(values))
            assert (s["min"], s["max"], s["n"]) == (min(values), max(values), 3)
    goals = report["summary"]["acceptance"]["residual"]
    assert all(g["folds"] == 3 and 0 <= g["met"] <= 3 for g in goals.values())
    assert report["summary"]["test"]["copy"] == report["test"]["scores"]["copy"]["metrics"]
    text = format_report(report, markdown=True)
    assert "| metric | copy [3] | copy-scaled [3] | residual [3] | residual@best-val [3] |" in text
    assert "test fold 07+13 (trained on 02+03+05+06+08+10+12+14)" in text


def test_resume_of_a_finished_run_trains_and_scores_nothing(
    finished: tuple[Path, dict[str, Any], list[str]], monkeypatch: pytest.MonkeyPatch
) -> None:
    out, report, _ = finished

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("resume repeated finished work")

    monkeypatch.setattr("robot_retarget.evaluation.crossval.train", refuse)
    monkeypatch.setattr("robot_retarget.evaluation.crossval.evaluate", refuse)
    config = tiny_config(Path(report["data_dir"]), out, out.parent / "cache")
    again = crossval(config, resume=True)
    assert again["summary"] == report["summary"]
    assert len(again["resumed"]) == 1


def test_an_interrupted_run_resumes_where_it_stopped(tmp_path: Path) -> None:
    subjects = {"02": "j31", "03": "j31", "07": "j31", "10": "j43", "12": "j43", "13": "j43"}
    data = make_tiny_set(tmp_path / "mocap", subjects)
    plan = FoldPlan(("07", "13"), (("02", "10"), ("03", "12")))
    config = tiny_config(data, tmp_path / "out", tmp_path / "cache", folds=plan)

    def stop_in_cv2(fold: str, p: TrainProgress) -> None:
        if fold == "cv-2" and p.step == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        crossval(config, progress=stop_in_cv2)
    stored = json.loads((tmp_path / "out" / CROSSVAL_JSON).read_text())
    assert stored["folds"] == {"test": ["07", "13"], "cv": [["02", "10"], ["03", "12"]]}
    assert "residual" in stored["cv"][0]["scores"]
    assert "residual" not in stored["cv"][1]["scores"]
    with pytest.raises(CrossvalError, match="pass --resume"):
        crossval(config)
    lines: list[str] = []
    report = crossval(config, resume=True, log=lines.append)
    assert "cv-1: residual already trained and scored" in lines
    assert any(line.startswith("cv-2: training residual") and "(resumed)" in line for line in lines)
    assert report["cv"][1]["runs"]["residual"]["last_step"] == 2
    assert set(report["test"]["scores"]) == {*BASELINES, "residual"}
    with pytest.raises(CrossvalError, match=r"\['steps'\] differ"):
        crossval(dataclasses.replace(config, steps=3), resume=True)


def test_refusals(tmp_path: Path) -> None:
    data = make_tiny_set(tmp_path / "mocap")
    cache = tmp_path / "cache"
    with pytest.raises(CrossvalError, match="choose from nkn, pmnet, residual, tdcn"):
        crossval(tiny_config(data, tmp_path / "o1", cache, models=("copy",)))
    with pytest.raises(CrossvalError, match="choose from"):
        crossval(tiny_config(data, tmp_path / "o1", cache, models=("resnet",)))
    with pytest.raises(DatasetError, match="no such data folder"):
        crossval(tiny_config(tmp_path / "missing", tmp_path / "o1", cache))
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(CrossvalError, match="not empty"):
        crossval(tiny_config(data, tmp_path / "busy", cache))
    make_tiny_set(data, {"me": "j31"})
    with pytest.raises(FoldError, match=r"\['me'\] of the data are in no fold"):
        crossval(tiny_config(data, tmp_path / "o1", cache))
    assert not (tmp_path / "o1").exists()  # refused before writing anything
    assert issubclass(FoldError, RetargetError)
