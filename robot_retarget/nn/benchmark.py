"""``bench model``: time per frame of a retargeting model, online (one ``step`` per frame) and
per clip (one forward pass, time divided by the frames). Models the live pipeline runs in numpy
(copy, copy-scaled, residual) get a third row, ``online-numpy``, in the same run.

The goal is ≤ 0.3 ms median per frame on one core for NKN and PMnet online. The input is a
synthetic motion (smooth random rotations on the default canonical skeleton, a walking root)
retargeted onto OP3-sized proportions, so no data set is needed; timing does not depend on the
motion. A name that is a trainable architecture with no shipped checkpoint (``nkn``,
``pmnet``, ``residual``) is timed with freshly initialised weights of the default sizes (the
record's ``weights`` says which).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
import torch

from robot_retarget.array_types import FloatArray
from robot_retarget.bench_stats import TimingStats
from robot_retarget.errors import ModelLoadError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.nn.inference import (
    BUILTIN_MODELS,
    LoadedModel,
    OnlineRetargeter,
    load_model,
    retarget_clip,
    shipped_checkpoints,
)
from robot_retarget.nn.models.registry import MODELS, build_model
from robot_retarget.number_args import non_negative_int, positive_int
from robot_retarget.runtime.loader import names_runtime_file
from robot_retarget.runtime.model import RuntimeModel, load_runtime
from robot_retarget.skeleton.canonical import default_canonical_skeleton

HELP = "Retargeting model time per frame, online and per clip (median, p99)."


_DEFAULT_MODELS = ("copy", "nkn", "pmnet", "residual")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--model",
        action="append",
        default=None,
        help="model name, checkpoint path or exported runtime .npz (timed online-numpy only) "
        f"(repeatable; default: {', '.join(_DEFAULT_MODELS)})",
    )
    parser.add_argument(
        "--frames", type=positive_int, default=1000, help="timed frames (default 1000)"
    )
    parser.add_argument("--warmup", type=non_negative_int, default=100, help="untimed frames first")
    parser.add_argument(
        "--clip-repeats", type=positive_int, default=5, help="timed whole-clip passes"
    )
    parser.add_argument(
        "--threads", type=positive_int, default=1, help="torch CPU threads (default 1: one core)"
    )
    parser.add_argument(
        "--mode", choices=("online", "clip", "both"), default="both", help="what to time"
    )


def synthetic_motion(frames: int, seed: int = 0) -> tuple[FloatArray, FloatArray]:
    """Smooth random local rotations (T, 22, 4) and a walking root path (T, 3), metres."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None, None] / 30.0
    amp = rng.uniform(0.1, 0.5, size=(1, 22, 3))
    freq = rng.uniform(0.3, 1.5, size=(1, 22, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(1, 22, 3))
    q = quat.from_rotation_vector(amp * np.sin(2 * np.pi * freq * t + phase))
    root = np.stack(
        [0.1 * np.sin(t[:, 0, 0]), 0.9 + 0.02 * np.sin(4 * t[:, 0, 0]), 1.2 * t[:, 0, 0]], -1
    )
    return q, root


def resolve(name: str) -> tuple[LoadedModel, str]:
    """The model to time and whether it has ``trained`` / ``untrained`` / ``none`` weights."""
    if name in BUILTIN_MODELS:
        return load_model(name), "none"
    if name in shipped_checkpoints() or name not in MODELS:
        return load_model(name), "trained"
    return LoadedModel(name=name, model=build_model(name).eval()), "untrained"


def _runtime_record(name: str, args: argparse.Namespace) -> dict[str, Any]:
    """An exported runtime's one row, ``online-numpy``: it holds no torch model to time."""
    if args.mode == "clip":
        raise ModelLoadError(
            f"{name}: an exported runtime steps online only (it holds no torch model for a "
            "whole-clip pass); time --mode online, or the .pt checkpoint it was exported from",
            model=name,
        )
    stats = time_online(load_runtime(name), args.frames, args.warmup, numpy_twin=True)
    return {
        "model": name,
        "mode": "online-numpy",
        "frames": args.frames,
        "median_ms": stats.median_ms,
        "p99_ms": stats.p99_ms,
        "weights": "trained",
        "threads": args.threads,
    }


def has_numpy_twin(model: LoadedModel) -> bool:
    """Whether the live pipeline runs ``model``'s online step in numpy instead of torch."""
    from robot_retarget.runtime.loader import online_retargeter

    src = default_canonical_skeleton().offsets
    return not isinstance(online_retargeter(model, src, src), OnlineRetargeter)


def _target_offsets() -> FloatArray:
    # A third of an adult: robot-sized proportions without reading a robot config.
    return np.asarray(default_canonical_skeleton().offsets * 0.33, dtype=np.float64)


def time_online(
    model: LoadedModel | RuntimeModel, frames: int, warmup: int, numpy_twin: bool = False
) -> TimingStats:
    """Per-frame time of the online step: torch (``OnlineRetargeter``), or with ``numpy_twin``
    the numpy step the live pipeline runs (robot_retarget.runtime.copy.online_retargeter; a
    :class:`RuntimeModel` has only that one)."""
    if isinstance(model, RuntimeModel) and not numpy_twin:
        raise ValueError("a numpy runtime has no torch step: time it with numpy_twin=True")
    from robot_retarget.runtime.loader import online_retargeter
    from robot_retarget.runtime.model import OnlineStep

    q, root = synthetic_motion(frames + warmup)
    src, tgt = default_canonical_skeleton().offsets, _target_offsets()
    online: OnlineStep = (
        online_retargeter(model, src, tgt)
        if numpy_twin or isinstance(model, RuntimeModel)  # (the second: for the type checker)
        else OnlineRetargeter(model, src, tgt)
    )
    online.reset()
    durations = []
    for i in range(frames + warmup):
        start = time.perf_counter()
        online.step(q[i], root[i])
        if i >= warmup:
            durations.append(time.perf_counter() - start)
    return TimingStats.from_seconds(durations)


def time_clip(model: LoadedModel, frames: int, repeats: int) -> TimingStats:
    """Per-frame time of whole-clip passes (each pass's time / frames)."""
    q, root = synthetic_motion(frames)
    src = default_canonical_skeleton().offsets
    tgt = _target_offsets()
    retarget_clip(model, q[: min(frames, 30)], root[: min(frames, 30)], src, tgt)  # warm up
    durations = []
    for _ in range(repeats):
        start = time.perf_counter()
        retarget_clip(model, q, root, src, tgt)
        durations.append((time.perf_counter() - start) / frames)
    return TimingStats.from_seconds(durations)


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    names = args.model or list(_DEFAULT_MODELS)
    if args.frames < 1 or args.warmup < 0 or args.clip_repeats < 1:
        raise ModelLoadError(
            f"--frames ({args.frames}) and --clip-repeats ({args.clip_repeats}) must be ≥ 1 "
            f"and --warmup ({args.warmup}) ≥ 0"
        )
    previous = torch.get_num_threads()
    torch.set_num_threads(args.threads)
    records: list[dict[str, Any]] = []
    try:
        for name in names:
            if name == "agnostic2d":  # the 2D keypoint model: pixels in, not rotations
                from robot_retarget.nn.keypoint_benchmark import time_keypoint_model

                records += time_keypoint_model(
                    args.frames, args.warmup, args.clip_repeats, args.threads
                )
                continue
            if names_runtime_file(name):
                records.append(_runtime_record(name, args))
                continue
            model, weights = resolve(name)
            modes: tuple[str, ...] = ("online", "clip") if args.mode == "both" else (args.mode,)
            if "online" in modes and has_numpy_twin(model):
                modes = ("online", "online-numpy", *modes[1:])
            for mode in modes:
                if mode.startswith("online"):
                    stats = time_online(
                        model, args.frames, args.warmup, numpy_twin=mode == "online-numpy"
                    )
                else:
                    stats = time_clip(model, args.frames, args.clip_repeats)
                records.append(
                    {
                        "model": name,
                        "mode": mode,
                        "frames": args.frames,
                        "median_ms": stats.median_ms,
                        "p99_ms": stats.p99_ms,
                        "weights": weights,
                        "threads": args.threads,
                    }
                )
    finally:
        torch.set_num_threads(previous)
    return records
