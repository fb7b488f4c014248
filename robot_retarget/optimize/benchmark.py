"""``bench solve``: time the Retargeter on targets derived from real mocap.

Both modes on the same targets: ``online`` (one warm-started solve per frame, timed per call
from Python, as a live stream calls it) and ``offline`` (the whole clip in sliding windows; its
per-frame times are each window's time over the frames it commits, plus the frame-by-frame
seed pass's average). ``frames_per_s`` is frames over total wall time in both modes.

A clip shorter than ``--frames`` is played forwards and backwards until long enough (no jumps).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.bench_stats import TimingStats
from robot_retarget.errors import MotionFormatError
from robot_retarget.number_args import positive_int
from robot_retarget.optimize.retargeter import Retargeter
from robot_retarget.optimize.targets import ClipTargets, targets_from_rotations

HELP = "Retargeting optimizer: online (per frame) and offline (windows) solve times."

DEFAULT_CLIP = Path("mocap") / "02" / "02_05.bvh"  # CMU 02_05: punching / boxing, 120 fps


def _data_dir() -> Path:
    default = Path(__file__).resolve().parents[2].parent / "shared" / "data"
    return Path(os.environ.get("ROBOT_RETARGET_DATA", default))


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path (op3)")
    parser.add_argument(
        "--frames", type=positive_int, default=1200, help="frames per mode (default 1200)"
    )
    parser.add_argument(
        "--clip",
        type=Path,
        default=None,
        help=f"BVH clip (default: $ROBOT_RETARGET_DATA/{DEFAULT_CLIP})",
    )
    parser.add_argument(
        "--no-jit", action="store_true", help="interpreted solver (what runs without a compiler)"
    )
    parser.add_argument(
        "--mode", choices=("online", "offline", "both"), default="both", help="modes to run"
    )


def _pingpong(targets: ClipTargets, frames: int) -> ClipTargets:
    n = len(targets)
    idx = np.arange(frames) % (2 * n)
    idx = np.where(idx < n, idx, 2 * n - 1 - idx)

    def pick(a: np.ndarray[Any, np.dtype[np.float64]] | None) -> Any:
        return None if a is None else a[idx]

    return ClipTargets(
        directions=targets.directions[idx],
        normals=pick(targets.normals),
        ee_positions=pick(targets.ee_positions),
        ee_weights=targets.ee_weights,
        root_height_m=pick(targets.root_height_m),
    )


def load_targets(retargeter: Retargeter, clip: Path, frames: int) -> tuple[ClipTargets, float]:
    """(targets of ``frames`` frames, dt_s) from a BVH clip."""
    from robot_retarget.motion import load_motion

    if clip.is_dir():
        raise MotionFormatError("a folder: --clip names one BVH clip", path=clip)
    if not clip.is_file():
        raise MotionFormatError(
            "benchmark clip not found: pass --clip PATH or set ROBOT_RETARGET_DATA", path=clip
        )
    motion = load_motion(clip, max_frames=frames)
    targets = targets_from_rotations(
        retargeter.problem,
        motion.skeleton,
        motion.local_quats,
        root_pos=motion.root_pos,
        level_feet=retargeter.settings.level_feet,
    )
    if len(targets) < frames:
        targets = _pingpong(targets, frames)
    return targets, 1.0 / motion.fps


def bench_online(retargeter: Retargeter, targets: ClipTargets, dt_s: float) -> dict[str, Any]:
    retargeter.warm_up()
    retargeter.reset()
    frames = [targets.frame(t) for t in range(len(targets))]
    durations = []
    start = time.perf_counter()
    for f in frames:
        t0 = time.perf_counter()
        retargeter.solve(f, dt_s)
        durations.append(time.perf_counter() - t0)
    wall = time.perf_counter() - start
    stats = TimingStats.from_seconds(durations)
    return {
        "mode": "online",
        "frames": len(frames),
        "median_ms": stats.median_ms,
        "p99_ms": stats.p99_ms,
        "frames_per_s": len(frames) / wall,
    }


def bench_offline(retargeter: Retargeter, targets: ClipTargets, dt_s: float) -> dict[str, Any]:
    retargeter.solve_clip(targets.slice(0, min(len(targets), 4)), dt_s)  # builds the solver
    start = time.perf_counter()
    _, timing = retargeter.solve_clip(targets, dt_s)
    wall = time.perf_counter() - start
    seed_per_frame = timing.seed_time_s / len(targets)
    per_frame = [
        wt / n + seed_per_frame
        for wt, n in zip(timing.window_times_s, timing.window_frames, strict=True)
        for _ in range(n)
    ]
    stats = TimingStats.from_seconds(per_frame)
    return {
        "mode": "offline",
        "frames": len(targets),
        "median_ms": stats.median_ms,
        "p99_ms": stats.p99_ms,
        "frames_per_s": len(targets) / wall,
    }


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config(args.robot)
    retargeter = Retargeter(config, jit=not args.no_jit)
    clip = args.clip if args.clip is not None else _data_dir() / DEFAULT_CLIP
    targets, dt_s = load_targets(retargeter, clip, args.frames)
    records = []
    if args.mode in ("online", "both"):
        records.append(bench_online(retargeter, targets, dt_s))
    if args.mode in ("offline", "both"):
        records.append(bench_offline(retargeter, targets, dt_s))
    return records
