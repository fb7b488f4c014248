"""``demo --input 2d``: the built-in routine seen as 2D keypoints, lifted, streamed and
converted, passing every check including following the routine's 3D ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from robot_retarget.cli import demo_cmd
from robot_retarget.motion.trajectory import RobotTrajectory

TIME_LIMIT_S = 90


def test_short_2d_demo_passes_its_checks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    parser = argparse.ArgumentParser()
    demo_cmd.configure(parser)
    out = tmp_path / "demo"
    args = parser.parse_args(["--out-dir", str(out), "--seconds", "4", "--input", "2d",
                              "--no-preview"])  # fmt: skip
    assert demo_cmd.run(args) == 0
    text = capsys.readouterr().out
    assert "FAIL" not in text, text
    assert "[PASS] 2D input follows the routine" in text
    assert RobotTrajectory.read(out / "demo_op3_2d.npz").num_frames == 501
    assert not (out / "demo_op3.npz").exists()  # the 3D demo's outputs are left alone


def test_a_keypoint_model_that_looks_ahead_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The 2D demo lifts frame by frame, as ``stream`` does: a centred model is refused with
    the reason (no traceback, nothing written)."""
    from robot_retarget.cli.main import main

    out = tmp_path / "demo"
    rc = main(["demo", "--out-dir", str(out), "--seconds", "2", "--input", "2d", "--no-preview",
               "--keypoint-model", "agnostic2d_clip"])  # fmt: skip
    assert rc != 0
    err = capsys.readouterr().err
    assert "looks ahead" in err
    assert "Traceback" not in err
    assert not out.exists() or not list(out.glob("*.npz"))
