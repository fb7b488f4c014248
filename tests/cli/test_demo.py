"""``demo``: the built-in clip end to end (short version: 2 s of the routine at 2× speed)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from PIL import Image

from robot_retarget.cli import demo_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.motion.trajectory import RobotTrajectory

TIME_LIMIT_S = 90


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    demo_cmd.configure(parser)
    return parser.parse_args(list(argv))


def test_short_demo_passes_its_checks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "demo"
    assert demo_cmd.run(_args("--out-dir", str(out), "--seconds", "2", "--speed", "2")) == 0
    text = capsys.readouterr().out
    assert "FAIL" not in text, text
    assert text.count("[PASS]") == 5
    traj = RobotTrajectory.read(out / "demo_op3.npz")
    assert traj.num_frames == 126  # 2 s at 2× speed = 1 s at 125 Hz
    assert RobotTrajectory.read(out / "demo_op3_stream.npz").num_frames > 100
    assert (out / "demo_op3.bvh").read_text().startswith("HIERARCHY")
    with Image.open(out / "demo_preview.gif") as im:
        assert 5 <= im.n_frames <= 200
    with pytest.raises(RetargetError, match="--force"):
        demo_cmd.run(_args("--out-dir", str(out), "--seconds", "2"))


def test_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(RetargetError, match="--seconds"):
        demo_cmd.run(_args("--out-dir", str(tmp_path), "--seconds", "20"))
