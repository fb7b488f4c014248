"""eval-robot plots (matplotlib, Agg backend): per-segment error bars and a stick-figure strip."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.robot.runner import METHOD_LABELS, METHODS, EvalRobotReport
from robot_retarget.evaluation.robot.segments import KINDS, RobotBodyModel, body_axes, to_body
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint

_UP = np.array([0.0, 1.0, 0.0])


def segment_bars(report: EvalRobotReport, path: Path) -> Path:
    """Grouped bars: mean direction error per segment kind and overall, one bar per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [*KINDS, "overall"]
    x = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(8, 4))
    width = 0.8 / len(METHODS)
    for k, m in enumerate(METHODS):
        vals = [report.summary[m].segment_mean_deg[lab] for lab in labels]
        ax.bar(x + (k - 0.5 * (len(METHODS) - 1)) * width, vals, width, label=METHOD_LABELS[m])
    ax.set_xticks(x, [lab.replace("_", " ") for lab in labels])
    ax.set_ylabel("direction error (°)")
    ax.set_title(f"{report.robot}, model {report.model}: segment-direction error")
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _front(v: FloatArray) -> FloatArray:
    """Body-frame points (…, 3) → 2D front view as seen by a viewer facing the body."""
    return np.stack([-v[..., 1], v[..., 2]], axis=-1)


def stick_strip(
    report: EvalRobotReport, model: RobotBodyModel, path: Path, *, clip: int = 0, count: int = 5
) -> Path:
    """Human (top) and robot (pipeline, bottom) stick figures, front view, ``count`` frames
    spread over one clip."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = report.clips[clip]
    n = c.human_positions.shape[0]
    picks = np.unique(np.linspace(0, n - 1, count).round().astype(int))
    fig, axes = plt.subplots(2, len(picks), figsize=(2.2 * len(picks), 5), squeeze=False)
    f = model.frames
    kin = model.kinematics
    chains = [
        [f.shoulders[0], f.starts[0], f.ends[0], f.ends[2]],
        [f.shoulders[1], f.starts[1], f.ends[1], f.ends[3]],
        [f.hips[0], f.starts[4], f.ends[4], f.ends[6]],
        [f.hips[1], f.starts[5], f.ends[5], f.ends[7]],
        [f.hips[0], f.hips[1], f.shoulders[1], f.shoulders[0], f.hips[0]],
    ]
    up = np.asarray(model.config.up_axis, dtype=np.float64)
    for col, t in enumerate(picks):
        pos = c.human_positions[t]
        ax_h = body_axes(pos[Joint.LeftUpLeg], pos[Joint.RightUpLeg], _UP)
        hips = 0.5 * (pos[Joint.LeftUpLeg] + pos[Joint.RightUpLeg])
        pts = _front(to_body(ax_h, pos - hips))
        ax = axes[0][col]
        for j, p in enumerate(CANONICAL_PARENTS):
            if p >= 0:
                ax.plot(pts[[p, j], 0], pts[[p, j], 1], "C0-", lw=2)
        ax.set_title(f"frame {t}", fontsize=8)
        q = c.robot_q["pipeline"][t]
        ax = axes[1][col]
        for chain in chains:
            rp = kin.frame_positions(q, chain)
            hp = kin.frame_positions(q, list(f.hips))
            ax_r = body_axes(hp[0], hp[1], up)
            rpts = _front(to_body(ax_r, rp - hp.mean(axis=0)))
            ax.plot(rpts[:, 0], rpts[:, 1], "C1-", lw=2)
        for a in (axes[0][col], axes[1][col]):
            a.set_aspect("equal")
            a.set_xticks([])
            a.set_yticks([])
    axes[0][0].set_ylabel("human")
    axes[1][0].set_ylabel("robot (pipeline)")
    fig.suptitle(f"{c.name}: front view, heading-free body frame", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
