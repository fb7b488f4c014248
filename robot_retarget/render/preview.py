"""Side-by-side stick-figure preview of a human clip and its robot trajectory.

matplotlib (Agg, no display needed) draws both in 3D with Y up; GIFs go through Pillow, MP4s
through ffmpeg when it is installed (otherwise a PreviewError says so). Frames are subsampled
to ``fps`` and capped at ``max_frames`` so a preview stays small and quick to render.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import RetargetError
from robot_retarget.robot.canonical_skeleton import robot_to_canonical_rotation
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS

FORMATS: tuple[str, ...] = (".gif", ".mp4")


class PreviewError(RetargetError):
    """A preview cannot be written (unknown format, no ffmpeg for MP4, file exists)."""

    def __init__(self, message: str, *, path: str | Path | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)


def robot_points(config: RobotConfig, q: npt.ArrayLike) -> tuple[FloatArray, list[tuple[int, int]]]:
    """Link and fixed-frame positions (T, F, 3) in canonical axes (Y up) and the edges."""
    kin = RobotKinematics(config)
    c = robot_to_canonical_rotation(config)
    pts = kin.frame_positions(np.asarray(q, dtype=np.float64)) @ c.T
    chain = kin.chain
    n_links = len(chain.link_names)
    edges = [(int(p), k + 1) for k, p in enumerate(chain.link_parent)]
    edges += [(int(p), n_links + f) for f, p in enumerate(chain.frame_parent)]
    return pts, edges


def check_preview_path(path: str | Path, *, overwrite: bool = False) -> Path:
    """Validate the output path before any work: format, ffmpeg for MP4, no silent overwrite."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise PreviewError(f"preview must be .gif or .mp4, got {suffix or '(none)'!r}", path=p)
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise PreviewError(
            "MP4 previews need ffmpeg on the PATH (apt install ffmpeg); or write a .gif", path=p
        )
    if p.exists() and not overwrite:
        raise PreviewError("the file already exists; pass --force to replace it", path=p)
    return p


def render_preview(
    path: str | Path,
    human_positions: npt.ArrayLike,
    human_fps: float,
    config: RobotConfig,
    robot_q: npt.ArrayLike,
    robot_fps: float,
    *,
    fps: float = 10.0,
    max_frames: int = 200,
    size_in: tuple[float, float] = (6.0, 3.2),
    dpi: int = 80,
    title: str = "",
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write a preview: human (T, 22, 3) m Y-up at ``human_fps`` left, robot (T', J) right."""
    p = check_preview_path(path, overwrite=overwrite)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import animation
    from matplotlib import pyplot as plt
    from matplotlib.artist import Artist

    human = np.asarray(human_positions, dtype=np.float64)
    q = np.asarray(robot_q, dtype=np.float64)
    duration_s = min((human.shape[0] - 1) / human_fps, (q.shape[0] - 1) / robot_fps)
    count = max(1, min(max_frames, math.floor(duration_s * fps) + 1))
    t = np.arange(count) / fps
    hi = np.minimum(np.round(t * human_fps).astype(int), human.shape[0] - 1)
    ri = np.minimum(np.round(t * robot_fps).astype(int), q.shape[0] - 1)
    h = human[hi]
    h = h - np.array([h[0, 0, 0], 0.0, h[0, 0, 2]])  # start above the origin, feet on y = 0
    r, r_edges = robot_points(config, q[ri])
    r = r - np.array([0.0, float(r[:, :, 1].min()), 0.0])
    h_edges = [(p_, j) for j, p_ in enumerate(CANONICAL_PARENTS) if p_ >= 0]

    fig = plt.figure(figsize=size_in, dpi=dpi)
    panels = []
    for k, (pts, edges, label, color) in enumerate(
        ((h, h_edges, "human", "tab:blue"), (r, r_edges, config.name, "tab:orange"))
    ):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        lo, hi_ = pts.reshape(-1, 3).min(axis=0), pts.reshape(-1, 3).max(axis=0)
        centre = (lo + hi_) / 2
        half = float(max(hi_ - lo)) / 2 or 0.5
        # Plot (x, z, y): matplotlib's vertical axis is its third.
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[2] - half, centre[2] + half)
        ax.set_zlim(centre[1] - half, centre[1] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=12, azim=-70)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_zticks([])
        ax.set_title(label, fontsize=9)
        lines = [ax.plot([], [], [], color=color, lw=2)[0] for _ in edges]
        panels.append((pts, edges, lines))
    if title:
        fig.suptitle(title, fontsize=8)
    fig.tight_layout()

    def draw(i: int) -> Sequence[Artist]:
        artists: list[Artist] = []
        for pts, edges, lines in panels:
            for (a, b), line in zip(edges, lines, strict=True):
                seg = pts[i, [a, b]]
                line.set_data_3d(seg[:, 0], seg[:, 2], seg[:, 1])
                artists.append(line)
        if progress is not None:
            progress(i + 1, count)
        return artists

    anim = animation.FuncAnimation(fig, draw, frames=count, blit=False)
    writer: animation.AbstractMovieWriter
    if p.suffix.lower() == ".gif":
        writer = animation.PillowWriter(fps=round(fps))
    else:
        writer = animation.FFMpegWriter(fps=round(fps))
    tmp = p.with_name(p.stem + ".part" + p.suffix)
    try:
        anim.save(str(tmp), writer=writer, dpi=dpi)
        tmp.replace(p)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return p
