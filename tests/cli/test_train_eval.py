"""End to end through the command modules: train a tiny model, eval it, resume, bench it."""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import shutil
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from robot_retarget.cli import bench_cmd, convert_cmd, eval_cmd, train_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.nn import benchmark

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
SUBJECTS = {
    "s1": ("tiny_walk.bvh", "asf_names.bvh"),
    "s2": ("mixamo.bvh",),
    "s3": ("crlf_tabs.bvh",),
}


@pytest.fixture
def mocap(tmp_path: Path) -> Path:
    root = tmp_path / "mocap"
    for subject, files in SUBJECTS.items():
        (root / subject).mkdir(parents=True)
        for name in files:
            shutil.copy(FIXTURES / name, root / subject / name)
    return root


def _run(module: ModuleType, argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    module.configure(parser)
    code: int = module.run(parser.parse_args(argv))
    return code


def _train_args(mocap: Path, out: Path, cache: Path, steps: int) -> list[str]:
    return [
        "--model", "pmnet", "--data", str(mocap), "--out", str(out), "--steps", str(steps),
        "--batch-size", "4", "--window", "8", "--val-subjects", "s2", "--robots", "op3",
        "--val-every", "2", "--checkpoint-every", "2", "--log-every", "1",
        "--model-config", "hidden_size=16", "--model-config", "num_layers=1",
        "--model-config", "movement_channels=8", "--disc-config", "channels=[4,4,4,4]",
        "--cache-dir", str(cache), "--threads", "1",
    ]  # fmt: skip


def test_train_eval_resume(mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, cache = tmp_path / "runs" / "tiny", tmp_path / "cache"
    assert _run(train_cmd, _train_args(mocap, out, cache, 2)) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["steps"] == 2
    assert "2/2" in captured.err  # the progress bar
    assert (out / "best.pt").is_file()
    # ... and its numpy runtime beside it, which streams without torch and agrees with it.
    assert summary["runtime"] == str(out / "best.npz")
    from robot_retarget.runtime.model import load_runtime

    assert (
        load_runtime(out / "best.npz").checkpoint_sha256
        == hashlib.sha256((out / "best.pt").read_bytes()).hexdigest()
    )

    eval_args = ["--data", str(mocap), "--val-subjects", "s2,s3", "--cache-dir", str(cache)]
    code = _run(
        eval_cmd,
        ["--model", "copy", "--model", str(out), "--json", "--max-frames", "10", *eval_args],
    )
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["subjects"] == ["s2", "s3"]
    assert report["robots"] == ["op3"]
    assert [r["model"] for r in report["results"]] == ["copy", str(out / "best.pt")]
    for r in report["results"]:
        # The fixture clips share one skeleton, so op3 is each clip's only distinct target.
        assert r["pairs"] == 2
        assert r["metrics"]["ee"] is not None

    assert _run(eval_cmd, ["--model", "copy-scaled", "--robot", "none", *eval_args]) == 0
    table = capsys.readouterr().out
    assert table.startswith("model")
    assert "no robot" in table

    assert _run(train_cmd, [*_train_args(mocap, out, cache, 3), "--resume"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["steps"] == 3

    # The run's checkpoint can be benchmarked like any model.
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    args = parser.parse_args(["--model", str(out / "last.pt"), "--frames", "20", "--warmup", "2"])
    records = benchmark.run(args)
    assert [(r["mode"], r["weights"]) for r in records] == [
        ("online", "trained"),
        ("online-numpy", "trained"),  # a trained PMnet: the live pipeline's numpy step too
        ("clip", "trained"),
    ]
    assert all(r["median_ms"] > 0 and r["p99_ms"] >= r["median_ms"] for r in records)
    assert bench_cmd.format_table(records).startswith("model")


def test_train_refuses_resuming_another_model(mocap: Path, tmp_path: Path) -> None:
    out, cache = tmp_path / "run", tmp_path / "cache"
    assert _run(train_cmd, _train_args(mocap, out, cache, 1)) == 0
    args = _train_args(mocap, out, cache, 2)
    args[1] = "nkn"
    with pytest.raises(RetargetError, match="pass --model pmnet"):
        _run(train_cmd, [*args, "--resume"])
    # Settings given again with other values were silently ignored (the stored ones trained):
    # now refused by name; --steps no larger than the run's is no resume either.
    args = _train_args(mocap, out, cache, 2)
    with pytest.raises(RetargetError, match=r"--lr \(0.001, the run has 0.0001\) differs"):
        _run(train_cmd, [*args, "--resume", "--lr", "1e-3"])
    with pytest.raises(RetargetError, match=r"--data .* differs"):
        _run(train_cmd, [*args[:3], str(tmp_path), *args[4:], "--resume"])
    with pytest.raises(RetargetError, match="already at step 1, and --steps 1 asks for no more"):
        _run(train_cmd, [*_train_args(mocap, out, cache, 1), "--resume"])


def test_bad_model_config_is_a_clear_error(mocap: Path, tmp_path: Path) -> None:
    args = _train_args(mocap, tmp_path / "r", tmp_path / "c", 1)
    with pytest.raises(RetargetError, match="expected KEY=VALUE"):
        _run(train_cmd, [*args, "--model-config", "oops"])


@pytest.mark.parametrize(
    ("model", "extra", "message"),
    [
        ("pmnet", ["--model-config", "hidden_size=-5"], "--model-config: pmnet cannot be built"),
        ("pmnet", ["--disc-config", "bogus=3"], "--disc-config: pmnet cannot be built"),
        ("residual", ["--disc-config", "channels=3"], "trained without a discriminator"),
        ("tdcn", ["--window", "31"], "a window needs at least 32 frames; pass --window 32"),
    ],
)  # fmt: skip
def test_a_network_that_cannot_be_built_is_one_line_before_the_data(
    mocap: Path, tmp_path: Path, model: str, extra: list[str], message: str
) -> None:
    """These had ended in tracebacks from torch (some after the data load; a TDCN's --window
    16 asked for 31 frames, then refused 31)."""
    args = [
        "--model", model, "--data", str(mocap), "--out", str(tmp_path / "r"), "--steps", "1",
        "--batch-size", "4", "--window", "8", "--val-subjects", "s2", "--robots", "op3",
        "--cache-dir", str(tmp_path / "c"), "--threads", "1",
    ]  # fmt: skip
    with pytest.raises(RetargetError, match=message):
        _run(train_cmd, [*args, *extra])
    assert not (tmp_path / "r").exists()


def test_bench_defaults_cover_copy_nkn_pmnet_residual() -> None:
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    args = parser.parse_args(["--frames", "5", "--warmup", "1", "--clip-repeats", "1"])
    records = benchmark.run(args)
    assert {r["model"] for r in records} == {"copy", "nkn", "pmnet", "residual"}
    assert {"model", "mode", "frames", "median_ms", "p99_ms"} <= set(records[0])
    # The live pipeline's numpy steps are timed next to the torch ones, in the same run.
    numpy_rows = {r["model"] for r in records if r["mode"] == "online-numpy"}
    assert numpy_rows == {"copy", "pmnet", "residual"}


def test_eval_scores_a_whole_folder_of_other_performers(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder holding none of the training split's validation subjects (s1–s3 here) is scored
    whole, as is any folder with --val-subjects all; named subjects still pick their clips."""
    base = ["--model", "copy", "--data", str(mocap), "--json", "--cache-dir", str(tmp_path / "c")]
    base += ["--max-frames", "20"]

    def clips_scored(extra: list[str]) -> int:
        assert _run(eval_cmd, base + extra) == 0
        report = json.loads(capsys.readouterr().out)
        return int(report["results"][0]["clips"])

    assert clips_scored([]) == 4
    assert clips_scored(["--val-subjects", "all"]) == 4
    assert clips_scored(["--val-subjects", "s1"]) == 2


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--val-subjects", ","], "--val-subjects ',' names no subject"),  # scored 0 clips, exit 0
        (["--val-subjects", ""], "--val-subjects '' names no subject"),  # the default subjects
        (["--model", "copy", "--model", "copy"], "--model copy given twice"),  # two equal rows
        (["--robot", "none", "--robot", "op3"], "--robot none (no robot target) contradicts"),
    ],
)
def test_eval_refuses_what_it_would_misread_before_any_work(
    tmp_path: Path, argv: list[str], says: str
) -> None:
    with pytest.raises(SystemExit, match=re.escape(says)):
        _run(eval_cmd, [*argv, "--data", str(tmp_path / "none")])


def test_eval_json_and_markdown_exclude_each_other(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        _run(eval_cmd, ["--json", "--markdown"])
    assert info.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_san_trains_and_is_scored_on_the_files_own_skeletons(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, cache = tmp_path / "runs" / "san", tmp_path / "cache"
    args = [
        "--model", "san", "--data", str(mocap), "--out", str(out), "--steps", "2",
        "--batch-size", "4", "--window", "8", "--val-subjects", "s2", "--robots", "op3",
        "--val-every", "2", "--checkpoint-every", "2", "--model-config", "channels=[4,8]",
        "--model-config", "static_channels=2", "--model-config", "kernel_size=3",
        "--disc-config", "channels=8", "--disc-config", "dilations=[1,2]",
        "--cache-dir", str(cache), "--threads", "1",
    ]  # fmt: skip
    assert _run(train_cmd, args) == 0
    capsys.readouterr()
    eval_args = ["--data", str(mocap), "--val-subjects", "s2,s3", "--cache-dir", str(cache)]
    code = _run(
        eval_cmd,
        ["--model", str(out), "--model", "copy", "--native-input", "--json", *eval_args],
    )
    assert code == 0
    rows = [r["model"] for r in json.loads(capsys.readouterr().out)["results"]]
    best = str(out / "best.pt")
    # The SAN twice (canonical joints, then each file's own), copy once: it has no encoders.
    assert rows == [best, f"{best} (file's skeleton)", "copy"]

    # convert reads a BVH on its own skeleton through its encoder; --canonical-input does not.
    clip = mocap / "s1" / "tiny_walk.bvh"
    outs = {}
    for flag in ([], ["--canonical-input"]):
        path = tmp_path / f"walk{len(flag)}.npz"
        argv = [str(clip), "--robot", "op3", "--model", best, "--out", str(path), *flag]
        assert _run(convert_cmd, argv) == 0
        outs[len(flag)] = np.load(path)["q"]
    err = capsys.readouterr().err
    assert "tiny_walk.bvh: read on its own skeleton (CMU MotionBuilder-25j)" in err
    assert outs[0].shape == outs[1].shape
    assert not np.allclose(outs[0], outs[1])
    # Its exported runtime reads the canonical joints wherever the file lies (beside best.pt
    # it had read the clip's own skeleton, elsewhere not: the same bytes, two results).
    elsewhere = tmp_path / "elsewhere.npz"
    shutil.copy(out / "best.npz", elsewhere)
    for runtime in (out / "best.npz", elsewhere):
        path = tmp_path / f"walk_{runtime.stem}.npz"
        argv = [str(clip), "--robot", "op3", "--model", str(runtime), "--out", str(path)]
        assert _run(convert_cmd, argv) == 0
        np.testing.assert_array_equal(np.load(path)["q"], outs[1])


def test_eval_scores_the_network_without_its_foot_lock_beside_it(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--without-foot-lock adds a row per model that has a lock (as the robot path runs it) and
    none for models without one."""
    argv = ["--model", "default", "--model", "copy", "--data", str(mocap), "--json",
            "--cache-dir", str(tmp_path / "c"), "--max-frames", "60",
            "--without-foot-lock"]  # fmt: skip
    assert _run(eval_cmd, argv) == 0
    results = json.loads(capsys.readouterr().out)["results"]
    assert [r["model"] for r in results] == ["default", "default, no foot lock", "copy"]
    scores = [{k: v for k, v in r.items() if k != "model"} for r in results[:2]]
    assert scores[0] != scores[1]  # the lock holds a foot somewhere in these walks


def test_eval_says_when_without_foot_lock_adds_no_row(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["--model", "copy", "--without-foot-lock", "--data", str(mocap), "--json"]
    argv += ["--max-frames", "20", "--cache-dir", str(tmp_path / "c")]
    assert _run(eval_cmd, argv) == 0
    captured = capsys.readouterr()
    assert "note: --without-foot-lock scores models that have a foot lock" in captured.err
    assert len(json.loads(captured.out)["results"]) == 1


def test_eval_scores_a_folder_of_validation_subjects_alone(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """eval trains nothing: a folder holding only the subjects named was refused ("leave at
    least one for training")."""
    only = tmp_path / "only"
    shutil.copytree(mocap / "s2", only / "s2")
    args = ["--data", str(only), "--model", "copy", "--max-frames", "10", "--json",
            "--cache-dir", str(tmp_path / "c")]  # fmt: skip
    assert _run(eval_cmd, [*args, "--val-subjects", "s2"]) == 0
    assert json.loads(capsys.readouterr().out)["subjects"] == ["s2"]
