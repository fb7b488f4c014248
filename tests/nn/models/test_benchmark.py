"""``bench model`` target: records for every requested model and mode."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.nn.checkpoint import save_checkpoint
from robot_retarget.nn.models import benchmark
from robot_retarget.nn.models.registry import build_model


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    return parser.parse_args(list(argv))


def test_records_per_model_and_mode() -> None:
    records = benchmark.run(_args("--models", "copy", "copy-scaled", "--frames", "30"))
    assert [(r["model"], r["mode"]) for r in records] == [
        ("copy", "online"),
        ("copy", "clip"),
        ("copy-scaled", "online"),
        ("copy-scaled", "clip"),
    ]
    online = records[0]
    assert online["frames"] == 30
    assert 0.0 < online["median_ms"] <= online["p99_ms"]


def test_times_a_checkpoint(tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path / "tiny.pt", build_model("pmnet", hidden_size=8))
    records = benchmark.run(_args("--checkpoint", str(path), "--frames", "10", "--window", "8"))
    assert {r["model"] for r in records} == {"pmnet (tiny.pt)"}


def test_pingpong_has_no_jumps() -> None:
    played = benchmark.pingpong(np.arange(4), 11)
    assert played.tolist() == [0, 1, 2, 3, 3, 2, 1, 0, 0, 1, 2]


def test_rejects_unknown_models() -> None:
    with pytest.raises(SystemExit):
        _args("--models", "tdcn")
