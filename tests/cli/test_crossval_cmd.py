"""``crossval`` through the command line: a plan from --folds FILE, the JSON, Markdown and
plain outputs, and errors as one line on stderr."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from robot_retarget.cli.main import main

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
SUBJECTS = {"a": "tiny_walk.bvh", "b": "mixamo.bvh", "c": "asf_names.bvh", "t": "crlf_tabs.bvh"}


@pytest.fixture
def mocap(tmp_path: Path) -> Path:
    root = tmp_path / "mocap"
    for subject, name in SUBJECTS.items():
        (root / subject).mkdir(parents=True)
        shutil.copy(FIXTURES / name, root / subject / name)
    return root


def _argv(mocap: Path, out: Path, *extra: str) -> list[str]:
    plan = out.parent / "plan.json"
    plan.write_text(json.dumps({"test": ["t"], "cv": [["a", "b"], ["c"]]}))
    return [
        "crossval", "--model", "residual", "--data", str(mocap), "--out", str(out),
        "--steps", "1", "--batch-size", "4", "--window", "8", "--train-robots", "op3",
        "--model-config", "hidden_size=16", "--model-config", "num_layers=1",
        "--folds", str(plan), "--cache-dir", str(out.parent / "cache"), "--threads", "1",
        *extra,
    ]  # fmt: skip


def test_crossval_json_then_resume_as_markdown(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cv"
    assert main(_argv(mocap, out, "--json")) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report == json.loads((out / "crossval.json").read_text())
    assert report["folds"] == {"test": ["t"], "cv": [["a", "b"], ["c"]]}
    assert [e["train_subjects"] for e in report["cv"]] == [["c"], ["a", "b"]]
    assert report["test"]["train_subjects"] == ["a", "b", "c"]
    assert "cv-1: training residual" in captured.err
    assert "cv-1: step 1/1" in captured.err
    assert main([*_argv(mocap, out, "--markdown"), "--resume"]) == 0
    text = capsys.readouterr().out
    assert "| metric | copy [2] | copy-scaled [2] | residual [2] | residual@best-val [2] |" in text
    assert "test fold t (trained on a+b+c)" in text
    assert "crossval.json" in text


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("--model", "resnet"), "cannot cross-validate model(s) ['resnet']"),
        (("--data", "MISSING"), "no such data folder"),
        # Checked before crossval.json is written: a typo must not leave a folder behind that
        # --resume then refuses.
        (("--robot", "op4"), "no robot config named 'op4'"),
        (("--resume", ""), "--resume: nothing to resume"),  # it started a new cross-validation
        # A model that cannot be built had written crossval.json first: the retry was refused
        # ("pass --resume") and so was the resume ("model_config differs").
        (("--model-config", "hidden_size=-5"), "--model-config: residual cannot be built"),
    ],
)
def test_errors_are_one_line(
    mocap: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    change: tuple[str, str],
    message: str,
) -> None:
    argv = _argv(mocap, tmp_path / "cv")
    option, value = change
    value = str(tmp_path / value) if value == "MISSING" else value
    if option in argv:
        argv[argv.index(option) + 1] = value
    else:
        argv += [option, value] if value else [option]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ")
    assert message in err
    assert "Traceback" not in err
    assert not (tmp_path / "cv").exists()


def test_out_may_not_be_a_file(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "cv").write_text("")
    assert main(_argv(mocap, tmp_path / "cv")) == 1
    assert "a file, not a folder" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("option", "value"),
    [("--steps", "0"), ("--batch-size", "0"), ("--threads", "0"), ("--window", "1"),
     ("--lr", "-1"), ("--device", "tpu"), ("--val-every", "0")],
)  # fmt: skip
def test_values_no_training_can_run_with_are_usage_errors(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str
) -> None:
    """Before crossval.json is written (a run refused later left one behind, which the next
    run then refused to start over); --lr -1, --window 1 and --device tpu were tracebacks,
    the last after the data load and the copy baselines' scores."""
    argv = _argv(mocap, tmp_path / "cv")
    if option in argv:
        argv[argv.index(option) + 1] = value
    else:
        argv += [option, value]
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert f"argument {option}:" in capsys.readouterr().err
    assert not (tmp_path / "cv").exists()


def test_an_out_folder_that_cannot_be_made_is_one_line(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "file").write_text("")
    argv = _argv(mocap, tmp_path / "cv")
    argv[argv.index("--out") + 1] = str(tmp_path / "file" / "cv")  # was a FileNotFoundError
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: --out ")
    assert "cannot create the folder" in err
