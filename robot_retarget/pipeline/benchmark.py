"""``bench pipeline``: compute time per frame of the live path, stage by stage.

Stages, per frame of the built-in demo clip at the robot's control rate, as ``stream`` runs them
(:class:`robot_retarget.pipeline.step.RetargetStep`): ``decode`` (a binary UDP rotations packet →
a checked SourceFrame, as the receiver thread does), ``network`` (the model's online step),
``targets`` (rotations → targets, the online problem's parameters and velocity box: one compiled
call, :mod:`robot_retarget.optimize.live_frame`), ``optimizer`` (the warm-started SQP and its
checks), ``safety`` (SafetyLayer clamp) and ``total`` (decode to safety, the step's bookkeeping
included). The ``numpy path`` rows time the same frames, alternating with the first, through a
step that builds targets and parameters in numpy (``RetargetStep(frame_program=False)``); its
total adds the frame's decode and safety. ``--positions`` decodes position packets instead
(adds the minimal-twist solver).
Pin to one core for the figure that matters: ``taskset -c 1 python launch.py bench pipeline``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

from robot_retarget.bench_stats import stage_records
from robot_retarget.cli.foot_lock_arg import add_foot_lock_argument
from robot_retarget.number_args import non_negative_int, positive_int
from robot_retarget.pipeline.defaults import MODEL_HELP

HELP = "Per-frame compute time of the live path: decode, network, targets, optimizer, safety."

STAGES: tuple[str, ...] = ("decode", "network", "targets", "optimizer", "safety", "total")
# The same frames through a second step that builds targets and parameters in numpy
# (RetargetStep(frame_program=False)), alternating frame by frame with the first.
NUMPY_STAGES: tuple[str, ...] = (
    "targets, numpy path",
    "optimizer, numpy path",
    "total, numpy path",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument("--model", help=MODEL_HELP)
    parser.add_argument("--frames", type=positive_int, default=3000, help="timed frames")
    parser.add_argument("--warmup", type=non_negative_int, default=200, help="untimed frames first")
    parser.add_argument(
        "--positions", action="store_true", help="decode position packets (+ rotation solver)"
    )
    parser.add_argument(
        "--source",
        choices=("3d", "2d"),
        default="3d",
        help="2d: from a UDP COCO-17 keypoint packet through the keypoint model "
        "(robot_retarget.pipeline.benchmark_2d)",
    )
    parser.add_argument("--keypoint-model", help="--source 2d: keypoint model .npz")
    add_foot_lock_argument(parser)


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.hardware.safety import SafetyLayer
    from robot_retarget.hardware.types import JointCommand
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.pipeline.recorder import RecordingBackend
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.runtime.loader import load_runtime_model
    from robot_retarget.sources import wire
    from robot_retarget.sources.udp import UdpSource

    if args.frames < 1 or args.warmup < 0:
        raise ValueError("--frames must be ≥ 1 and --warmup ≥ 0")
    from robot_retarget.errors import RetargetError

    if args.source == "2d" and args.positions:
        raise RetargetError(
            "--positions times the 3D position packets; --source 2d times keypoint packets: "
            "pass one of them"
        )
    if args.source == "3d" and args.keypoint_model is not None:
        raise RetargetError("--keypoint-model is about --source 2d's keypoint packets: add it")
    if args.source == "2d":
        from robot_retarget.pipeline.benchmark_2d import run_2d

        return run_2d(args)
    config = load_robot_config(args.robot)
    rate = config.control_rate_hz
    dt = 1.0 / rate
    motion = demo_motion(fps=rate)
    positions = motion.positions()
    model = load_runtime_model(args.model or default_model_name())
    receiver = UdpSource(skeleton=motion.skeleton)  # never started: decode path only
    lock = args.foot_lock
    step = RetargetStep(config, model, motion.skeleton, foot_lock=lock)
    reference = RetargetStep(config, model, motion.skeleton, frame_program=False, foot_lock=lock)
    for s in (step, reference):
        s.retargeter.warm_up()
        s.reset(config.init_pose)
    safety = SafetyLayer(
        dataclasses.replace(config, control_rate_hz=rate), RecordingBackend(config)
    )
    safety.connect()
    kind = wire.KIND_POSITIONS if args.positions else wire.KIND_ROTATIONS
    times: dict[str, list[float]] = {s: [] for s in STAGES + NUMPY_STAGES}
    n = motion.num_frames
    for k in range(args.warmup + args.frames):
        i = k % n
        values = positions[i] if args.positions else motion.local_quats[i]
        root = None if args.positions else motion.root_pos[i]
        packet = wire.encode_binary(kind, k, k * dt, values, root)
        t0 = time.perf_counter()
        frame = receiver.handle_packet(packet, t0)
        t1 = time.perf_counter()
        if frame is None:
            raise RuntimeError(f"benchmark packet {k} was dropped: {receiver.stats.summary()}")
        out = step(frame.local_quats, frame.root_pos, dt)
        t2 = time.perf_counter()
        safety.send(JointCommand(out.q, k * dt * (1.0 + 1e-9)))
        t3 = time.perf_counter()
        receiver.poll(t3)  # keep the receiver's queue empty, as the loop does
        t4 = time.perf_counter()
        ref = reference(frame.local_quats, frame.root_pos, dt)
        t5 = time.perf_counter()
        if k >= args.warmup:
            network, targets, solve = out.times_s
            spans = (t1 - t0, network, targets, solve, t3 - t2, t3 - t0)
            for name, d in zip(STAGES, spans, strict=True):
                times[name].append(d)
            # The reference's own step time, with this frame's decode and safety.
            ref_total = (t1 - t0) + (t5 - t4) + (t3 - t2)
            for name, d in zip(NUMPY_STAGES, (*ref.times_s[1:], ref_total), strict=True):
                times[name].append(d)
    return stage_records(STAGES + NUMPY_STAGES, times)
