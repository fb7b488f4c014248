"""``bench model --model FILE.npz``: an exported runtime is timed as the live pipeline runs it
(online-numpy, its only step); it was refused as "already exported"."""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import pytest

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn import benchmark

RUNTIME = Path(benchmark.__file__).resolve().parents[1] / "data" / "checkpoints" / "default.npz"


def _run(*argv: str) -> list[dict[str, object]]:
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    return benchmark.run(parser.parse_args([*argv, "--frames", "20", "--warmup", "2"]))


def test_an_exported_runtime_is_timed_online_numpy(tmp_path: Path) -> None:
    renamed = tmp_path / "default.bin"  # told by content, not by its name
    shutil.copy(RUNTIME, renamed)
    for name in (str(RUNTIME), str(renamed)):
        (record,) = _run("--model", name)
        assert (record["model"], record["mode"], record["weights"]) == (
            name,
            "online-numpy",
            "trained",
        )
        assert 0 < record["median_ms"] <= record["p99_ms"]  # type: ignore[operator]


def test_what_a_runtime_cannot_time_is_named(tmp_path: Path) -> None:
    with pytest.raises(ModelLoadError, match=r"steps online only.*--mode online"):
        _run("--model", str(RUNTIME), "--mode", "clip")
    with pytest.raises(ModelLoadError, match=r"gone\.npz"):
        _run("--model", str(tmp_path / "gone.npz"))
