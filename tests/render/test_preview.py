from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.render import preview
from robot_retarget.render.preview import PreviewError, render_preview, robot_points
from robot_retarget.robot.config import RobotConfig


def test_gif_has_one_frame_per_tick(op3: RobotConfig, clip: HumanMotion, tmp_path: Path) -> None:
    q = np.tile(op3.init_pose, (11, 1))
    q[:, 0] = np.linspace(-0.5, 0.5, 11)
    ticks: list[int] = []
    out = render_preview(
        tmp_path / "p.gif",
        clip.positions(),
        clip.fps,
        op3,
        q,
        20.0,
        fps=10.0,
        size_in=(3.0, 1.6),
        dpi=40,
        title="test",
        progress=lambda d, t: ticks.append(d),
    )
    with Image.open(out) as im:
        assert im.n_frames == 6  # 0.5 s of overlap at 10 fps
        assert im.size == (120, 64)
    assert ticks[-1] == 6
    assert not list(tmp_path.glob("*.part*"))


def test_frame_cap(op3: RobotConfig, clip: HumanMotion, tmp_path: Path) -> None:
    out = render_preview(
        tmp_path / "p.gif", clip.positions(), clip.fps, op3, np.tile(op3.init_pose, (6, 1)),
        10.0, max_frames=3, size_in=(2.0, 1.0), dpi=30,
    )  # fmt: skip
    with Image.open(out) as im:
        assert im.n_frames == 3


def test_existing_file_and_bad_format(op3: RobotConfig, clip: HumanMotion,
                                      tmp_path: Path) -> None:  # fmt: skip
    existing = tmp_path / "e.gif"
    existing.write_bytes(b"keep")
    args = (clip.positions(), clip.fps, op3, np.tile(op3.init_pose, (2, 1)), 10.0)
    with pytest.raises(PreviewError, match="--force"):
        render_preview(existing, *args)
    assert existing.read_bytes() == b"keep"
    with pytest.raises(PreviewError, match=r"\.gif or \.mp4"):
        render_preview(tmp_path / "p.avi", *args)


def test_mp4_without_ffmpeg_is_a_clear_error(monkeypatch: pytest.MonkeyPatch,
                                             tmp_path: Path) -> None:  # fmt: skip
    monkeypatch.setattr(preview.shutil, "which", lambda name: None)
    with pytest.raises(PreviewError, match="ffmpeg"):
        preview.check_preview_path(tmp_path / "p.mp4")


def test_robot_points_edges_connect_frames(op3: RobotConfig) -> None:
    pts, edges = robot_points(op3, op3.init_pose[None])
    assert pts.shape[0] == 1
    assert all(0 <= a < pts.shape[1] and 0 <= b < pts.shape[1] for a, b in edges)
    # Y is up: the head is above the feet in the init pose.
    assert pts[0, :, 1].max() - pts[0, :, 1].min() > 0.2
