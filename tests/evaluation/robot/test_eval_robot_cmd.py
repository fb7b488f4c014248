"""The eval-robot command: arguments, output, errors (real clips, first frames only)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import pytest

from robot_retarget.cli import eval_robot_cmd


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    eval_robot_cmd.configure(parser)
    return parser.parse_args(list(argv))


def test_json_and_plots(
    shared_data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = shared_data_dir / "mocap"
    args = _args("--data", str(data), "--val-subjects", "12", "--max-frames", "60", "--json",
                 "--plots", str(tmp_path), "--cache-dir", "none", "--model", "oracle",
                 "--set", "w_orientation=0.05")  # fmt: skip
    assert eval_robot_cmd.run(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["robot"] == "op3"
    assert out["model"] == "oracle (--set w_orientation=0.05)"  # the override on record
    assert len(out["clips"]) == 3
    skate = {m: v["foot_skate_m_s"] for m, v in out["summary"].items()}
    assert skate["limit"] is None  # per-frame poses: no feet that move
    assert all(0.0 <= skate[m] < 2.0 for m in ("pipeline", "gmr", "baseline")), skate
    # Under the performer's planted feet only: part of every foot point's sliding.
    planted = {m: v["planted_skate_m_s"] for m, v in out["summary"].items()}
    assert planted["limit"] is None
    assert all(0.0 <= planted[m] <= skate[m] for m in ("pipeline", "gmr", "baseline")), planted
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "eval_robot_op3_segments.png",
        "eval_robot_op3_strip.png",
    ]


def test_unknown_subject_is_an_error(
    shared_data_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = _args("--data", str(shared_data_dir / "mocap"), "--val-subjects", "99")
    assert eval_robot_cmd.run(args) == 1
    assert "no clips of subjects" in capsys.readouterr().err


def test_bad_override() -> None:
    with pytest.raises(SystemExit):
        eval_robot_cmd.run(_args("--set", "w_orientation"))


def test_an_override_out_of_range_is_named_as_the_command_lines(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert eval_robot_cmd.run(_args("--set", "level_feet=1.5")) == 1
    err = capsys.readouterr().err
    assert "--set: key 'retarget.level_feet': must be a share 0 … 1, got 1.5" in err
    assert "op3.yaml" not in err


def test_corrupt_refuses_an_unknown_kind(capsys: pytest.CaptureFixture[str],
                                         shared_data_dir: Path) -> None:  # fmt: skip
    parser = argparse.ArgumentParser()
    eval_robot_cmd.configure(parser)
    args = parser.parse_args(["--data", str(shared_data_dir / "mocap"), "--corrupt", "fog"])
    assert eval_robot_cmd.run(args) == 1
    assert "unknown kind(s) ['fog']" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("model", "message"),
    [("oracle", "the oracle has no network"), ("copy-scaled", "'copy-scaled' has no foot lock")],
)
def test_foot_lock_is_refused_where_there_is_none(
    model: str, message: str, shared_data_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = _args("--data", str(shared_data_dir / "mocap"), "--val-subjects", "12",
                 "--model", model, "--foot-lock")  # fmt: skip
    assert eval_robot_cmd.run(args) == 1
    assert message in capsys.readouterr().err


def test_foot_lock_reaches_the_pipeline_and_the_report(
    shared_data_dir: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from robot_retarget.evaluation.robot import runner

    asked: list[dict[str, Any]] = []
    real = runner.pipeline_runner

    def recording(config: Any, model: str, **options: Any) -> Any:
        asked.append(options)
        return real(config, model, **options)

    monkeypatch.setattr(runner, "pipeline_runner", recording)
    args = _args("--data", str(shared_data_dir / "mocap"), "--val-subjects", "12",
                 "--max-frames", "40", "--json", "--cache-dir", "none", "--foot-lock")  # fmt: skip
    assert eval_robot_cmd.run(args) == 0
    assert asked == [{"foot_lock": True, "place_feet": True}]
    assert json.loads(capsys.readouterr().out)["model"] == "default + foot lock"
    asked.clear()
    args = _args("--data", str(shared_data_dir / "mocap"), "--val-subjects", "12",
                 "--max-frames", "40", "--json", "--cache-dir", "none",
                 "--feet-as-solved")  # fmt: skip
    assert eval_robot_cmd.run(args) == 0
    assert asked == [{"foot_lock": False, "place_feet": False}]
    assert json.loads(capsys.readouterr().out)["model"] == "default, feet as solved"


def test_feet_as_solved_is_refused_with_corrupt() -> None:
    with pytest.raises(SystemExit, match="--feet-as-solved is about the clip rows"):
        eval_robot_cmd.run(_args("--corrupt", "jitter", "--feet-as-solved"))
