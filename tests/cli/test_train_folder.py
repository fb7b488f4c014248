"""``train --out``: a folder that holds a run is refused unless --resume or --force; --steps
must be positive; a folder that cannot be made is a one-line error. All before any work."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from robot_retarget.cli import train_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.nn.run_folder import clear_run


def _args(out: Path, *extra: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    train_cmd.configure(parser)
    return parser.parse_args(["--model", "residual", "--out", str(out), *extra])


def test_a_folder_holding_a_run_needs_resume_or_force(tmp_path: Path) -> None:
    out = tmp_path / "run"
    train_cmd._claim_run_folder(_args(out))  # a new folder is made
    assert out.is_dir()
    for name in ("config.json", "log.csv", "best.pt", "events.out.tfevents.1.host"):
        (out / name).write_text("old run")
    (out / "notes.txt").write_text("mine")
    with pytest.raises(train_cmd.TrainArgumentError, match=r"already holds a run.*--resume"):
        train_cmd._claim_run_folder(_args(out))
    assert (out / "best.pt").read_text() == "old run"  # refused: nothing touched
    train_cmd._claim_run_folder(_args(out, "--resume"))
    assert (out / "log.csv").exists()  # resuming keeps the run
    train_cmd._claim_run_folder(_args(out, "--force"))
    assert (out / "best.pt").exists()  # deleted by the training once its data have loaded
    clear_run(out)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]  # only the run's files go
    with pytest.raises(train_cmd.TrainArgumentError, match="pass one"):
        train_cmd._claim_run_folder(_args(out, "--force", "--resume"))


def test_force_is_refused_under_torchrun(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("WORLD_SIZE", "2")
    with pytest.raises(train_cmd.TrainArgumentError, match="under torchrun"):
        train_cmd._claim_run_folder(_args(tmp_path / "run", "--force"))


def test_a_refused_run_deletes_nothing(tmp_path: Path) -> None:
    """--force with a setting the training refuses: the old run is still there."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "last.pt").write_text("old run")
    args = _args(out, "--force", "--live-noise", "2", "--data", str(tmp_path / "none"))
    with pytest.raises(RetargetError, match="live-noise"):
        train_cmd.run(args)
    assert (out / "last.pt").read_text() == "old run"


def test_steps_and_an_unmakeable_folder_are_refused(tmp_path: Path) -> None:
    with pytest.raises(train_cmd.TrainArgumentError, match="--steps must be at least 1, got 0"):
        train_cmd._claim_run_folder(_args(tmp_path / "a", "--steps", "0"))
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(train_cmd.TrainArgumentError, match="cannot create the run folder"):
        train_cmd._claim_run_folder(_args(blocker / "run"))
