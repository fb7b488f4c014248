"""Synthetic leading T-pose frames: found in the MotionBuilder conversion, not in DAZ."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.motion.bvh import parse_bvh, read_bvh
from robot_retarget.motion.tpose import count_synthetic_tpose_frames


def test_mb2_clips_have_one_synthetic_frame(mocap_dir: Path) -> None:
    for clip in ("02/02_01.bvh", "05/05_13.bvh", "06/06_04.bvh", "08/08_10.bvh"):
        assert count_synthetic_tpose_frames(read_bvh(mocap_dir / clip, max_frames=30)) == 1


def test_clip_07_12_has_two(mocap_dir: Path) -> None:
    assert (
        count_synthetic_tpose_frames(read_bvh(mocap_dir / "07" / "07_12.bvh", max_frames=30)) == 2
    )


def test_daz_first_frame_is_real(mocap_dir: Path) -> None:
    for clip in ("10/10_04.bvh", "13/13_11.bvh", "14/14_08.bvh"):
        assert count_synthetic_tpose_frames(read_bvh(mocap_dir / clip, max_frames=30)) == 0


def test_fixture_tiny_walk(motion_fixtures: Path) -> None:
    clip = read_bvh(motion_fixtures / "tiny_walk.bvh")
    assert count_synthetic_tpose_frames(clip) == 1
    assert count_synthetic_tpose_frames(clip.frames(1)) == 0


def _clip(rows: list[list[float]]) -> str:
    header = (
        "HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition "
        "Zrotation Yrotation Xrotation\n"
        + "".join(
            f"JOINT J{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Yrotation Xrotation\n"
            for k in range(3)
        )
        + "End Site\n{\nOFFSET 0 1 0\n}\n"
        + "}\n" * 4
    )
    body = "\n".join(" ".join(str(v) for v in r) for r in rows)
    return f"{header}MOTION\nFrames: {len(rows)}\nFrame Time: 0.01\n{body}\n"


def test_still_pose_and_smooth_start_are_not_tposes() -> None:
    still = [[0.0] * 15 for _ in range(20)]
    assert count_synthetic_tpose_frames(parse_bvh(_clip(still))) == 0
    smooth = [[0, 0, 0, *([0.0] * 3), *(np.full(9, 2.0 * k).tolist())] for k in range(20)]
    assert count_synthetic_tpose_frames(parse_bvh(_clip(smooth))) == 0


def test_zero_frame_then_jump_is_a_tpose() -> None:
    rows = [[0.0] * 15] + [[0, 0, 0, 0, 0, 0, *([40.0 + k] * 9)] for k in range(20)]
    assert count_synthetic_tpose_frames(parse_bvh(_clip(rows))) == 1
