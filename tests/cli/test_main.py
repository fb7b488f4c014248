"""The top-level CLI: errors as one line, a closed pipe without a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

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


_BLAS_PROBE = """
import ctypes, sys
from robot_retarget.cli.main import main
main(["inspect", "tests/fixtures/motion"])
import numpy  # already loaded by inspect; OpenBLAS read its thread count then
libs = [line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower()]
if not libs:
    print("no-openblas")
    sys.exit(0)
lib = ctypes.CDLL(libs[0])
for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_",
             "openblas_get_num_threads"):
    if hasattr(lib, name):
        print(getattr(lib, name)())
        break
else:
    print("no-getter")
"""


def test_numpy_runs_one_blas_thread_unless_the_user_says() -> None:
    """Small per-frame matrices: a second OpenBLAS thread costs more than it saves."""
    if not Path("/proc/self/maps").is_file():
        pytest.skip("needs /proc/self/maps to find the loaded OpenBLAS")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    runs = {}
    for label, extra in (("default", {}), ("user", {"OPENBLAS_NUM_THREADS": "2"})):
        out = subprocess.run([sys.executable, "-c", _BLAS_PROBE], cwd=REPO, env={**env, **extra},
                             capture_output=True, text=True, check=True)  # fmt: skip
        runs[label] = out.stdout.strip().splitlines()[-1]
    if runs["default"] in ("no-openblas", "no-getter"):
        pytest.skip(f"numpy's BLAS is not an OpenBLAS this test can ask ({runs['default']})")
    assert runs["default"] == "1"
    if (os.cpu_count() or 1) >= 2:  # OpenBLAS caps its threads at the cores it sees
        assert runs["user"] == "2"
