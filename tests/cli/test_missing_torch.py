"""Without torch: the commands that run on the numpy runtimes run, the others say in one line
what they need (they, and ``bench --help``, ended in an import traceback)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

_NO_TORCH = (
    "import sys; sys.modules['torch'] = None\n"  # an import of torch now fails, as uninstalled
    "from robot_retarget.cli.main import main\n"
    "sys.exit(main(sys.argv[1:]))\n"
)


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", _NO_TORCH, *args],
        capture_output=True, text=True, timeout=300, cwd=cwd, check=False,
    )  # fmt: skip


def test_bench_help_lists_every_benchmark_and_says_which_needs_torch(tmp_path: Path) -> None:
    done = _run("bench", "--help", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    for target in ("solve", "loop", "model", "pipeline", "convert", "stream"):
        assert target in done.stdout
    assert "needs torch" in done.stdout
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize(
    "argv",
    [("bench", "model"), ("export", "x.pt", "--out", "x.npz"), ("train", "--help")],
)
def test_a_command_that_needs_torch_says_so_in_one_line(
    argv: tuple[str, ...], tmp_path: Path
) -> None:
    done = _run(*argv, cwd=tmp_path)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "needs torch" in lines[0]
    assert "pip install torch==2.13.0" in lines[0]
    assert "convert, stream" in lines[0].lower()
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_convert_runs_and_a_misspelt_model_is_named_as_such(
    tmp_path: Path, shared_data_dir: Path
) -> None:
    clip = shared_data_dir / "mocap" / "02" / "02_01.bvh"
    done = _run("convert", str(clip), "--robot", "op3", "--out", "a.npz", "--max-frames", "60",
                cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "a.npz").is_file()
    done = _run("convert", str(clip), "--robot", "op3", "--out", "b.npz", "--model", "nosuchmodel",
                cwd=tmp_path)  # fmt: skip
    assert done.returncode == 1
    assert "no model 'nosuchmodel'" in done.stderr
    assert "default" in done.stderr
    assert "torch is not installed" not in done.stderr
