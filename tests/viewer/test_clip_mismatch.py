"""``view --clip``: a clip whose length is not the trajectory's is warned about (it was drawn
beside it without a word); the clip a trajectory was converted from is not."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.cli.main import main
from robot_retarget.cli.view_cmd import clip_mismatch
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.motion.trajectory import RobotTrajectory

WALK = Path(__file__).resolve().parents[1] / "fixtures" / "motion" / "tiny_walk.bvh"


def test_the_converted_clip_fits_and_another_length_is_named(tmp_path: Path) -> None:
    for extra in ([], ["--lead-in"], ["--fps", "50"]):
        out = tmp_path / f"walk{len(extra)}{extra[-1] if extra else ''}.npz"
        assert main(["convert", str(WALK), "--out", str(out), *extra]) == 0
        clip = load_motion(WALK)
        assert clip_mismatch(clip.duration_s, clip.fps, RobotTrajectory.read(out)) is None
    longer = RobotTrajectory(("a",), np.zeros((300, 1)), 125.0)
    said = clip_mismatch(clip.duration_s, clip.fps, longer)
    assert said is not None
    assert said.startswith(f"--clip is {clip.duration_s:.2f} s long and the trajectory 2.40 s")
