"""``bench solve`` in a short mode, so the benchmark cannot rot."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.casadi_jit import CACHE_ENV
from robot_retarget.cli import bench_cmd
from robot_retarget.errors import MotionFormatError
from robot_retarget.optimize import benchmark
from robot_retarget.optimize.targets import ClipTargets

KEYS = {"mode", "frames", "median_ms", "p99_ms", "frames_per_s"}


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    bench_cmd.configure(parser)
    return parser.parse_args(argv)


def test_bench_solve_short(
    shared_data_dir: Path,
    cache_dir: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(cache_dir))
    clip = shared_data_dir / benchmark.DEFAULT_CLIP
    args = _parse(["solve", "--robot", "op3", "--frames", "30", "--clip", str(clip), "--json"])
    assert bench_cmd.run(args) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    records = [json.loads(line) for line in lines]
    assert [r["mode"] for r in records] == ["online", "offline"]
    for r in records:
        assert set(r) == KEYS
        assert r["frames"] == 30
        assert 0.0 < r["median_ms"] <= r["p99_ms"]
        assert r["frames_per_s"] > 0.0


def test_bench_solve_without_jit_one_mode(shared_data_dir: Path) -> None:
    clip = shared_data_dir / benchmark.DEFAULT_CLIP
    args = _parse(["solve", "--frames", "10", "--clip", str(clip), "--no-jit", "--mode", "online"])
    records = benchmark.run(args)
    assert [r["mode"] for r in records] == ["online"]


def test_missing_clip_is_a_clear_error(tmp_path: Path) -> None:
    args = _parse(["solve", "--frames", "10", "--clip", str(tmp_path / "none.bvh"), "--no-jit"])
    with pytest.raises(MotionFormatError, match="ROBOT_RETARGET_DATA"):
        benchmark.run(args)


def test_frames_must_be_positive(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        _parse(["solve", "--frames", "0"])
    assert "at least 1" in capsys.readouterr().err


def test_short_clips_play_back_and_forth() -> None:
    dirs = np.arange(3, dtype=float)[:, None, None] * np.ones((3, 1, 3))
    out = benchmark._pingpong(ClipTargets(dirs), 8)
    np.testing.assert_array_equal(out.directions[:, 0, 0], [0, 1, 2, 2, 1, 0, 0, 1])
