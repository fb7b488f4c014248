"""``bench model``: time the retargeting models, online (per frame) and per clip.

``online`` times :meth:`RetargetModel.step` once per frame, as a live stream calls it (eval
mode, ``torch.inference_mode``); ``clip`` times whole-clip forward passes over windows of
``--window`` frames and reports each window's time per frame. Models are built with the papers'
sizes and random weights (timing does not depend on the weight values) unless ``--checkpoint``
loads a trained one. The motion is the built-in 30 fps demo routine (no data needed), played
forwards and backwards to ``--frames``; the target is a robot's canonical skeleton.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from robot_retarget.bench_stats import TimingStats
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.registry import build_model, model_names

HELP = "Retargeting networks: online (per frame) and clip forward times."


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--models",
        nargs="+",
        choices=model_names(),
        default=list(model_names()),
        help="models to time (default: all)",
    )
    parser.add_argument("--checkpoint", type=Path, default=None, help="time a trained model")
    parser.add_argument("--robot", default="op3", help="target robot config (default op3)")
    parser.add_argument(
        "--frames", type=_positive_int, default=600, help="online frames (default 600)"
    )
    parser.add_argument("--window", type=_positive_int, default=60, help="clip window (60)")
    parser.add_argument(
        "--threads", type=_positive_int, default=1, help="torch intra-op threads (default 1)"
    )


def pingpong(values: np.ndarray[Any, Any], frames: int) -> np.ndarray[Any, Any]:
    """``frames`` frames of ``values`` (T, …) played forwards and backwards (no jumps)."""
    n = values.shape[0]
    idx = np.arange(frames) % (2 * n)
    return values[np.where(idx < n, idx, 2 * n - 1 - idx)]


def bench_online(
    model: RetargetModel,
    quats: torch.Tensor,
    root: torch.Tensor,
    src_offsets: torch.Tensor,
    tgt_offsets: torch.Tensor,
    warmup: int = 20,
) -> dict[str, Any]:
    """Per-frame step times over the clip (B = 1), after ``warmup`` untimed frames."""
    model.eval()
    durations = []
    with torch.inference_mode():
        model.reset()
        for t in range(min(warmup, quats.shape[1])):
            model.step(quats[:, t], root[:, t], src_offsets, tgt_offsets)
        model.reset()
        for t in range(quats.shape[1]):
            t0 = time.perf_counter()
            model.step(quats[:, t], root[:, t], src_offsets, tgt_offsets)
            durations.append(time.perf_counter() - t0)
    stats = TimingStats.from_seconds(durations)
    return {
        "mode": "online",
        "frames": len(durations),
        "median_ms": stats.median_ms,
        "p99_ms": stats.p99_ms,
    }


def bench_clip(
    model: RetargetModel,
    quats: torch.Tensor,
    root: torch.Tensor,
    src_offsets: torch.Tensor,
    tgt_offsets: torch.Tensor,
    window: int,
) -> dict[str, Any]:
    """Whole-window forward passes; per-frame time = window time / window length."""
    model.eval()
    per_frame = []
    starts = range(0, max(quats.shape[1] - window, 0) + 1, window)
    # no_grad, not inference_mode: caches the clip path builds must stay usable for training.
    with torch.no_grad():
        model(quats[:, :window], root[:, :window], src_offsets, tgt_offsets)  # warm-up
        for s in starts:
            t0 = time.perf_counter()
            model(quats[:, s : s + window], root[:, s : s + window], src_offsets, tgt_offsets)
            per_frame.append((time.perf_counter() - t0) / min(window, quats.shape[1] - s))
    stats = TimingStats.from_seconds(per_frame)
    return {
        "mode": "clip",
        "frames": len(per_frame) * window,
        "median_ms": stats.median_ms,
        "p99_ms": stats.p99_ms,
    }


def _models(args: argparse.Namespace) -> Sequence[tuple[str, RetargetModel]]:
    if args.checkpoint is not None:
        from robot_retarget.nn.checkpoint import load_checkpoint

        loaded = load_checkpoint(args.checkpoint).model
        return [(f"{loaded.name} ({args.checkpoint.name})", loaded)]
    return [(name, build_model(name)) for name in args.models]


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
    from robot_retarget.robot.loader import load_robot_config

    torch.set_num_threads(args.threads)
    motion = demo_motion(fps=30.0)
    frames = max(args.frames, args.window)
    quats = torch.tensor(pingpong(motion.local_quats, frames), dtype=torch.float32)[None]
    root = torch.tensor(pingpong(motion.root_pos, frames), dtype=torch.float32)[None]
    src = torch.tensor(np.array(motion.skeleton.offsets), dtype=torch.float32)[None]
    robot = robot_canonical_skeleton(load_robot_config(args.robot))
    tgt = torch.tensor(np.array(robot.offsets), dtype=torch.float32)[None]
    records: list[dict[str, Any]] = []
    for label, model in _models(args):
        for record in (
            bench_online(model, quats[:, : args.frames], root[:, : args.frames], src, tgt),
            bench_clip(model, quats, root, src, tgt, args.window),
        ):
            records.append({"model": label, "threads": args.threads, **record})
    return records
