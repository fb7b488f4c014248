"""The top-level CLI: errors as one line, a closed pipe without a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_a_reader_that_goes_away_is_not_an_error() -> None:
    """``inspect DIR | head -1``: the pipe closes early; no BrokenPipeError traceback."""
    cmd = f"{sys.executable} launch.py inspect tests/fixtures/motion | head -1"
    out = subprocess.run(cmd, shell=True, cwd=REPO, capture_output=True, text=True, check=False)
    assert out.stdout.count("\n") == 1
    assert "Traceback" not in out.stderr
    assert "BrokenPipeError" not in out.stderr


def test_a_missing_file_is_one_line() -> None:
    out = subprocess.run([sys.executable, "launch.py", "inspect", "no/such.bvh"], cwd=REPO,
                         capture_output=True, text=True, check=False)  # fmt: skip
    assert out.returncode == 1
    assert out.stderr.startswith("error: ")
    assert "Traceback" not in out.stderr
