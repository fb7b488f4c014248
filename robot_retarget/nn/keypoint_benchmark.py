"""``bench model --model agnostic2d``: the keypoint model's time per frame.

Rows: ``online`` (the causal step ``stream`` runs: features, encoders, head → 22 rotations,
one camera frame at a time, for the image and its mirror, the features and rotations
compiled), ``online-numpy`` (the same step all in numpy, its reference) and
``online-numpy-single`` (the numpy step on the image alone), the three timed alternately,
``clip-numpy`` (the causal model's whole-clip pass on the image alone, time / frames),
``convert-numpy`` (``convert``'s lifting: the shipped clip model, every model of its ensemble,
on the image and its mirror, time / frames) and ``clip`` (the torch model's forward pass,
time / frames).
Input: the built-in demo clip seen by a virtual camera with estimator-like noise (timing does
not depend on it).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import torch

from robot_retarget.bench_stats import TimingStats

NAME = "agnostic2d"


def time_keypoint_model(
    frames: int, warmup: int, repeats: int, threads: int
) -> list[dict[str, Any]]:
    from robot_retarget.keypoints.normalize import normalize_sequences
    from robot_retarget.keypoints.synthetic import EstimatorNoise, render_keypoints
    from robot_retarget.keypoints.virtual_camera import VirtualCamera
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.nn.agnostic2d_training import load_keypoint_checkpoint
    from robot_retarget.runtime.agnostic2d import (
        SHIPPED_KEYPOINT_MODEL,
        MirrorAveragedStep,
        load_keypoint_model,
    )

    motion = demo_motion(fps=30.0)
    cam = VirtualCamera(0.4, math.radians(15.0), 4.0, 1000.0)
    px, _conf, valid = render_keypoints(
        motion.positions(), motion.global_quats(), motion.height_m, cam,
        np.random.default_rng(0), EstimatorNoise(),
    )  # fmt: skip
    n = px.shape[0]
    runtime = load_keypoint_model()
    convert_model = load_keypoint_model(whole_clip=True)
    # The two steps alternate frame by frame, so both see the same machine load.
    compiled, single = runtime.online(), runtime.online(mirror_average=False)
    mirrored = MirrorAveragedStep(runtime.weights, compiled=False)
    online_compiled: list[float] = []
    online: list[float] = []
    online_single: list[float] = []
    for i in range(frames + warmup):
        steps = ((compiled, online_compiled), (mirrored, online), (single, online_single))
        for step, times in steps:
            t0 = time.perf_counter()
            step.step(px[i % n], valid[i % n])
            if i >= warmup:
                times.append(time.perf_counter() - t0)
    clip_np: list[float] = []
    convert_np: list[float] = []
    clip_torch: list[float] = []
    model, _payload = load_keypoint_checkpoint(SHIPPED_KEYPOINT_MODEL.with_suffix(".pt"))
    feats = torch.from_numpy(normalize_sequences(px[None], valid[None]).astype(np.float32))
    with torch.inference_mode():
        model(feats[:, :30], False)  # warm up
        for _ in range(repeats):
            t0 = time.perf_counter()
            runtime.run_clip(px, valid, causal=False)
            clip_np.append((time.perf_counter() - t0) / n)
            t0 = time.perf_counter()
            convert_model.run_clip(px, valid, causal=False, mirror_average=True)
            convert_np.append((time.perf_counter() - t0) / n)
            t0 = time.perf_counter()
            model(feats, False)
            clip_torch.append((time.perf_counter() - t0) / n)
    out = []
    rows = (("online", online_compiled, frames), ("online-numpy", online, frames),
            ("online-numpy-single", online_single, frames),
            ("clip-numpy", clip_np, n), ("convert-numpy", convert_np, n),
            ("clip", clip_torch, n))  # fmt: skip
    for mode, durations, count in rows:
        stats = TimingStats.from_seconds(durations)
        out.append({"model": NAME, "mode": mode, "frames": count, "median_ms": stats.median_ms,
                    "p99_ms": stats.p99_ms, "weights": "trained", "threads": threads})  # fmt: skip
    return out
