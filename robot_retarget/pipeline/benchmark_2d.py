"""``bench pipeline --source 2d``: the live path from a UDP keypoint packet to a servo command.

Input: the built-in demo clip seen by a 30 fps virtual camera (elevation 15°, 4 m, 1000 px)
with estimator-like noise, a second, smaller person beside the performer. Per camera frame
(as the receiver thread does): ``decode`` (a COCO-17 JSON packet with two people → checked
points, the person rule, the glitch gate: robot_retarget.keypoints.glitch_gate),
``keypoint model`` (the causal keypoint model's step: features, encoders, head → 22 canonical
rotations) and ``image planes`` (those rotations turned into the image's planes, the camera
fitted on the frames so far: robot_retarget.keypoints.online_reprojection; the warm-up's
camera frames are more than it needs to fit one). Per control tick, on the rotations
interpolated between the last two camera frames (as the control loop does), as ``bench
pipeline``: ``network``, ``targets``, ``optimizer`` (the three parts of
:class:`robot_retarget.pipeline.step.RetargetStep`), ``safety``. ``total``: a tick's stages
plus the camera frame's when one arrived on that tick; ``total, tick with a camera frame``:
those ticks only.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from typing import Any

import numpy as np

from robot_retarget.bench_stats import stage_records

STAGES_2D: tuple[str, ...] = (
    "decode",
    "keypoint model",
    "image planes",
    "network",
    "targets",
    "optimizer",
    "safety",
    "total",
    "total, tick with a camera frame",
)
CAMERA_FPS = 30.0


def run_2d(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.geometry import quaternion as quat
    from robot_retarget.hardware.safety import SafetyLayer
    from robot_retarget.hardware.types import JointCommand
    from robot_retarget.keypoints.glitch_gate import KeypointGate
    from robot_retarget.keypoints.online_reprojection import OnlineReprojection
    from robot_retarget.keypoints.synthetic import EstimatorNoise, render_keypoints
    from robot_retarget.keypoints.virtual_camera import VirtualCamera
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.pipeline.recorder import RecordingBackend
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.runtime.agnostic2d import load_keypoint_model
    from robot_retarget.runtime.loader import load_runtime_model
    from robot_retarget.sources.keypoints.person_choice import PersonTracker
    from robot_retarget.sources.keypoints.wire import decode_keypoints, encode_keypoints

    if args.frames < 1 or args.warmup < 0:
        raise ValueError("--frames must be ≥ 1 and --warmup ≥ 0")
    config = load_robot_config(args.robot)
    rate = config.control_rate_hz
    dt = 1.0 / rate
    motion = demo_motion(fps=CAMERA_FPS)
    camera = VirtualCamera(0.4, math.radians(15.0), 4.0, 1000.0)
    px, conf, _valid = render_keypoints(
        motion.positions(), motion.global_quats(), motion.height_m, camera,
        np.random.default_rng(0), EstimatorNoise(),
    )  # fmt: skip
    people = np.concatenate([np.nan_to_num(px), conf[..., None]], axis=-1)
    bystander = people.copy()
    bystander[..., :2] = bystander[..., :2] * 0.4 + 20.0
    keypoint_step = load_keypoint_model(args.keypoint_model).online()
    planes = OnlineReprojection(fps=CAMERA_FPS)
    tracker = PersonTracker()
    gate = KeypointGate(CAMERA_FPS)
    model = load_runtime_model(args.model or default_model_name())
    step = RetargetStep(config, model, motion.skeleton, foot_lock=args.foot_lock)
    step.retargeter.warm_up()
    step.reset(config.init_pose)
    safety = SafetyLayer(
        dataclasses.replace(config, control_rate_hz=rate), RecordingBackend(config)
    )
    safety.connect()
    root = motion.root_pos[0]
    times: dict[str, list[float]] = {s: [] for s in STAGES_2D}
    n = motion.num_frames
    frame = -1
    previous = current = None
    for k in range(args.warmup + args.frames):
        camera_t = k * dt * CAMERA_FPS
        arrived = 0.0
        if int(camera_t) != frame:  # a new camera frame: decode and lift it (receiver thread)
            frame = int(camera_t)
            packet = encode_keypoints(frame, frame / CAMERA_FPS, [bystander[frame % n],
                                      people[frame % n]], image_size=camera.image_size)  # fmt: skip
            t0 = time.perf_counter()
            pkt = decode_keypoints(packet, 0.3)
            chosen = tracker.choose([(xy, v) for xy, _c, v in pkt.people])
            if chosen is None:
                raise RuntimeError(f"benchmark frame {frame}: the performer was not followed")
            xy, _conf, valid = pkt.people[chosen]
            valid = gate.step(xy, valid, frame / CAMERA_FPS)  # as the source does
            t1 = time.perf_counter()
            lifted = keypoint_step.step(xy, valid)
            t2 = time.perf_counter()
            planes.set_image_size(pkt.image_size)  # as the source does
            previous, current = current, planes.step(lifted, np.where(valid[:, None], xy, np.nan))
            t3 = time.perf_counter()
            arrived = t3 - t0
            if k >= args.warmup:
                times["decode"].append(t1 - t0)
                times["keypoint model"].append(t2 - t1)
                times["image planes"].append(t3 - t2)
        assert current is not None
        # The control loop interpolates between the last two input frames.
        local = current if previous is None else quat.slerp(previous, current, camera_t - frame)
        t2 = time.perf_counter()
        out = step(local, root, dt)
        t3 = time.perf_counter()
        safety.send(JointCommand(out.q, k * dt * (1.0 + 1e-9)))
        t4 = time.perf_counter()
        if k >= args.warmup:
            for name, d in zip(STAGES_2D[3:7], (*out.times_s, t4 - t3), strict=True):
                times[name].append(d)
            times["total"].append(t4 - t2 + arrived)
            if arrived:
                times["total, tick with a camera frame"].append(t4 - t2 + arrived)
    return stage_records(STAGES_2D, times)
