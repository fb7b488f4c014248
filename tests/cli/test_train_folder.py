"""``train --out``: a folder that holds a run is refused unless --resume or --force; --steps
must be positive; a folder that cannot be made is a one-line error. All before any work."""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import pytest

from robot_retarget.cli import train_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.nn.run_folder import clear_run

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"


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


def _mocap(root: Path) -> Path:
    """Two subjects of the fixture clips (one to train on, one to validate)."""
    for subject, name in (("s1", "tiny_walk.bvh"), ("s2", "mixamo.bvh")):
        (root / subject).mkdir(parents=True)
        shutil.copy(FIXTURES / name, root / subject / name)
    return root


@pytest.mark.parametrize(
    ("extra", "error", "says"),
    [
        (["--window", "8", "--model-config", "no_such_option=1"], RetargetError, "no_such_option"),
        (["--window", "500"], RetargetError, "no clip has 500 frames"),
    ],
)
def test_force_deletes_the_old_run_only_once_the_new_one_can_start(
    tmp_path: Path, extra: list[str], error: type[Exception], says: str
) -> None:
    """A model setting or a window refused after the data have loaded: each was refused after
    the old run had been deleted (every checkpoint lost, only the new config.json left)."""
    out = tmp_path / "run"
    out.mkdir()
    for name in ("config.json", "last.pt", "best.pt", "best.npz"):
        (out / name).write_text("old run")
    data = _mocap(tmp_path / "mocap")
    args = _args(out, "--force", "--data", str(data), "--val-subjects", "s2", "--robots", "",
                 "--steps", "1", "--quiet", *extra)  # fmt: skip
    with pytest.raises(error, match=says):
        train_cmd.run(args)
    assert sorted(p.name for p in out.iterdir()) == ["best.npz", "best.pt", "config.json",
                                                      "last.pt"]  # fmt: skip
    assert all(p.read_text() == "old run" for p in out.iterdir())


def test_a_new_run_that_stops_before_its_first_checkpoint_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C (or any failure) in the first steps: no config.json stays behind to make the
    next run in that folder need --force."""
    from robot_retarget.nn import train as train_module

    def stop(*_: object, **__: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(train_module, "training_step", stop)
    out = tmp_path / "run"
    data = _mocap(tmp_path / "mocap")
    args = _args(out, "--data", str(data), "--val-subjects", "s2", "--robots", "",
                 "--steps", "2", "--batch-size", "2", "--window", "8", "--quiet",
                 "--model-config", "hidden_size=16")  # fmt: skip
    with pytest.raises(KeyboardInterrupt):
        train_cmd.run(args)
    assert not out.exists()


def test_a_subject_both_excluded_and_validated_on_is_named(tmp_path: Path) -> None:
    with pytest.raises(
        train_cmd.TrainArgumentError,
        match=r"--exclude-subjects leaves out 06, which --val-subjects \(06,08,12\) validates",
    ):
        train_cmd.run(_args(tmp_path / "run", "--exclude-subjects", "06"))
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("option", "value"),
    [("--batch-size", "0"), ("--window", "1"), ("--lr", "-1"), ("--device", "tpu"),
     ("--val-every", "0"), ("--checkpoint-every", "0"), ("--log-every", "0"),
     ("--threads", "0"), ("--steps", "0"), ("--loader-workers", "-1")],
)  # fmt: skip
def test_values_no_training_can_run_with_are_usage_errors(
    tmp_path: Path, option: str, value: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each was a traceback (ValueError, ZeroDivisionError after a step, torch's RuntimeError),
    some after the data had loaded and --force had deleted the old run."""
    with pytest.raises(SystemExit) as info:
        _args(tmp_path / "run", option, value)
    assert info.value.code == 2
    assert f"argument {option}:" in capsys.readouterr().err


def test_an_unmakeable_folder_is_refused(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(train_cmd.TrainArgumentError, match="cannot create the run folder"):
        train_cmd._claim_run_folder(_args(blocker / "run"))


def test_an_out_that_is_a_file_is_named_as_one(tmp_path: Path) -> None:
    """It said 'cannot create the run folder ([Errno 17] File exists …)'."""
    a_file = tmp_path / "c1.npz"
    a_file.write_text("not a run")
    with pytest.raises(train_cmd.TrainArgumentError, match="a file, not a folder"):
        train_cmd._claim_run_folder(_args(a_file))
    assert a_file.read_text() == "not a run"


def test_an_interrupted_run_says_what_it_kept_and_how_to_go_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C printed only 'interrupted': nothing on the checkpoint kept or on --resume."""
    import torch

    train_cmd._say_what_was_kept(tmp_path)
    assert "before its first checkpoint: nothing kept" in capsys.readouterr().err
    torch.save({"step": 7}, tmp_path / "trainer_state.pt")
    train_cmd._say_what_was_kept(tmp_path)
    err = capsys.readouterr().err
    assert "checkpoints of step 7" in err
    assert "--resume" in err
