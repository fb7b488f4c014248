"""2D keypoint input needs no torch: ``convert`` of a keypoint file runs in an interpreter where
``import torch`` fails, and gives the same robot motion as in this process."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
FOLDER = REPO / "tests" / "fixtures" / "keypoints" / "openpose_body25"

_CONVERT = """import sys
sys.modules['torch'] = None  # any import of torch now fails
import argparse
from robot_retarget.cli import convert_cmd
parser = argparse.ArgumentParser()
convert_cmd.configure(parser)
args = parser.parse_args([sys.argv[1], "--robot", "op3", "--out", sys.argv[2]])
assert convert_cmd.run(args) == 0
"""


def test_keypoint_convert_without_torch(tmp_path: Path) -> None:
    cmd = [sys.executable, "-c", _CONVERT, str(FOLDER), str(tmp_path / "a.npz")]
    out = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    import argparse

    from robot_retarget.cli import convert_cmd

    parser = argparse.ArgumentParser()
    convert_cmd.configure(parser)
    args = parser.parse_args([str(FOLDER), "--robot", "op3", "--out", str(tmp_path / "b.npz")])
    assert convert_cmd.run(args) == 0
    with np.load(tmp_path / "a.npz") as a, np.load(tmp_path / "b.npz") as b:
        np.testing.assert_allclose(a["q"], b["q"], atol=1e-9)
