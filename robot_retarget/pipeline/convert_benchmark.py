"""``bench convert``: a folder of real clips converted by 1, 2, ... Ray workers.

The clips (``--clips`` of them, spread evenly over the sorted clips under ``--data``, their
first ``--max-frames`` frames) are first converted in this process, one after another, as
``convert`` without ``--workers`` does: the reference. Then, per worker count, that many Ray
workers convert them again (robot_retarget.pipeline.clip_pool.RayClipPool) in one local Ray
instance with as many CPUs as the largest count. Start-up is timed on its own (Ray's,
``ray_init_s``; the workers' with their solver loads, ``startup_s``) and left out of the
throughput: frames/s is every clip's frames over the wall time from the first clip sent to the
last clip back; frames per CPU second (the converting processes' CPU time) is the per-worker
rate whatever else the machine runs. Per clip: median and p99 of the conversion's compute
seconds. The worker counts run in ``--repeat`` interleaved rounds (1, 2, 1, 2, ...): frames/s
(and per CPU second) is the median over the rounds, the speed-up the median (and range) of
each round's ratio to the first worker count's run of the same round, which cancels slow
drifts in the load of a shared machine.
Every run's files must equal the reference's bit for bit (every array but ``frame_ms``, the
measured compute time per frame).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.number_args import positive_int
from robot_retarget.pipeline.defaults import MODEL_HELP

HELP = "Folder conversion on 1, 2, ... Ray workers: frames/s, per-clip time, speed-up."

_COMPARED = ("q", "root_pos", "root_quat")


def configure(parser: argparse.ArgumentParser) -> None:
    from robot_retarget.cli.data_dir import add_data_argument

    add_data_argument(parser)
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument("--model", help=MODEL_HELP)
    parser.add_argument("--workers", default="1,2", help="worker counts, comma separated")
    parser.add_argument("--clips", type=positive_int, default=20, help="clips to convert")
    parser.add_argument(
        "--max-frames", type=positive_int, default=600, help="convert each clip's first N frames"
    )
    parser.add_argument(
        "--repeat", type=positive_int, default=3, help="rounds of every worker count, interleaved"
    )
    parser.add_argument(
        "--no-reference",
        action="store_true",
        help="skip the in-process reference conversion (and the bit-for-bit check)",
    )


def same_trajectory(a: Path, b: Path) -> bool:
    """Two trajectory files hold the same joint names, rate, start and arrays bit for bit
    (``frame_ms``, a measured time, is not compared)."""
    from robot_retarget.motion.trajectory import RobotTrajectory

    ta, tb = RobotTrajectory.read(a), RobotTrajectory.read(b)
    if (ta.joint_names, ta.fps, ta.t0) != (tb.joint_names, tb.fps, tb.t0):
        return False
    for key in _COMPARED:
        xa, xb = getattr(ta, key), getattr(tb, key)
        if (xa is None) != (xb is None):
            return False
        if xa is not None and not np.array_equal(xa, xb):
            return False
    return True


def pick_clips(data: Path, count: int) -> list[Path]:
    """``count`` clips spread evenly over the sorted .bvh files under ``data``."""
    from robot_retarget.errors import RetargetError

    clips = sorted(p for p in data.rglob("*.bvh"))
    if len(clips) < count:
        raise RetargetError(
            f"{data} holds {len(clips)} .bvh clip(s), fewer than --clips {count}: pass --data "
            "with more clips or a smaller --clips"
        )
    idx = np.linspace(0, len(clips) - 1, count).round().astype(int)
    return [clips[i] for i in idx]


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.errors import RetargetError
    from robot_retarget.pipeline.clip_converter import ClipJob, ClipReport, ConvertOptions
    from robot_retarget.pipeline.clip_pool import LocalClipPool, RayClipPool, import_ray
    from robot_retarget.pipeline.defaults import default_model_name

    counts = [int(w) for w in str(args.workers).split(",") if w.strip()]
    if not counts or min(counts) < 1:
        raise RetargetError(f"--workers must list counts >= 1, got {args.workers!r}")
    import_ray(max(counts))
    clips = pick_clips(Path(args.data), args.clips)
    options = ConvertOptions(
        robot=args.robot, model=args.model or default_model_name(), max_frames=args.max_frames
    )
    records: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="bench-convert-") as tmp:
        root = Path(tmp)

        def jobs(name: str) -> list[ClipJob]:
            return [ClipJob(c, root / name / f"{k:03d}_{c.stem}.npz", force=True, make_folders=True)
                    for k, c in enumerate(clips)]  # fmt: skip

        def record(mode: str, workers: int, startup_s: float, wall_s: float,
                   reports: list[ClipReport], name: str) -> dict[str, Any]:  # fmt: skip
            failed = [r for r in reports if r.error is not None]
            if failed:
                raise RetargetError(f"bench convert: {failed[0].clip} failed: {failed[0].error}")
            frames = sum(r.frames for r in reports)
            per_clip = np.array([r.wall_s for r in reports])
            rec: dict[str, Any] = {
                "target": "convert",
                "robot": args.robot,
                "mode": mode,
                "workers": workers,
                "clips": len(reports),
                "frames": frames,
                "startup_s": startup_s,
                "wall_s": wall_s,
                "frames_per_s": frames / wall_s,
                # Per worker, whatever else the machine runs: frames over the CPU seconds the
                # converting processes got (read, convert, write).
                "frames_per_cpu_s": frames / sum(r.cpu_s for r in reports),
                "clip_median_s": float(np.median(per_clip)),
                "clip_p99_s": float(np.percentile(per_clip, 99)),
            }
            if not args.no_reference and name != "reference":
                rec["bit_equal"] = all(
                    same_trajectory(j.out, r.out)
                    for j, r in zip(jobs(name), jobs("reference"), strict=True)
                )
            return rec

        if not args.no_reference:
            with LocalClipPool(options) as local:
                t0 = time.perf_counter()
                reports = list(local.convert(jobs("reference")))
                wall = time.perf_counter() - t0
            records.append(record("in-process", 1, local.startup_s, wall, reports, "reference"))
        ray = import_ray(max(counts))
        started_ray = not ray.is_initialized()
        t0 = time.perf_counter()
        if started_ray:  # once for every run: the pools join it, its start-up is not timed
            ray.init(
                address="local",
                num_cpus=max(counts),
                include_dashboard=False,
                log_to_driver=False,
                logging_level="warning",
            )
        ray_init_s = time.perf_counter() - t0
        runs: dict[int, list[dict[str, Any]]] = {w: [] for w in counts}
        try:
            for _ in range(args.repeat):  # interleaved: 1, 2, 1, 2, ... on a shared machine
                for w in counts:
                    name = f"ray{w}"
                    with RayClipPool(options, w) as pool:
                        t0 = time.perf_counter()
                        reports = list(pool.convert(jobs(name)))
                        wall = time.perf_counter() - t0
                    runs[w].append(record("ray", w, pool.startup_s, wall, reports, name))
        finally:
            if started_ray:
                ray.shutdown()
        first = runs[counts[0]]
        for w in counts:
            by_fps = sorted(runs[w], key=lambda r: float(r["frames_per_s"]))
            rec = dict(by_fps[len(by_fps) // 2])  # the median run's per-clip figures
            rec["ray_init_s"] = ray_init_s
            rec["runs"] = len(runs[w])
            rec["frames_per_s"] = float(np.median([r["frames_per_s"] for r in runs[w]]))
            rec["wall_s"] = float(np.median([r["wall_s"] for r in runs[w]]))
            rec["frames_per_cpu_s"] = float(np.median([r["frames_per_cpu_s"] for r in runs[w]]))
            rec["bit_equal"] = all(r.get("bit_equal", True) for r in runs[w])
            # Each run over the first count's run of the same round: load drifts between rounds.
            ratios = [
                r["frames_per_s"] / f["frames_per_s"] for r, f in zip(runs[w], first, strict=True)
            ]
            rec["speedup"] = float(np.median(ratios))
            rec["speedup_min"] = float(min(ratios))
            rec["speedup_max"] = float(max(ratios))
            records.append(rec)
    return records
