"""``eval-robot --input 2d``: the robot driven from a camera's 2D keypoints, scored against the
performer's 3D ground truth beside the same clip fed as 3D.

Per validation clip (subjects never trained on) and held-out view — elevations 0°, 15°, 30°
at azimuths 45°, 135°, 225°, 315°, 5 m, 1100 px (fixed views; training draws azimuth,
elevation −10…45°, distance and focal length at random, never these on these subjects):

1. **3D** — the clip through the full pipeline (network → optimizer → safety), as ``convert``;
2. **2D** — the clip resampled to a 30 fps camera, projected through the view with
   estimator-like noise (robot_retarget.keypoints.synthetic: pixel jitter, dropouts, bursts,
   hidden face points; its own random draws), lifted as ``convert`` does (``clip``: the centred
   keypoint model, whole-clip codes, bones turned into the image's planes:
   robot_retarget.keypoints.reprojection) and as ``stream`` does (``stream``: the causal model,
   codes of the frames so far, the planes with the camera fitted so far) — and sent through
   the same pipeline. The camera's azimuth is turned back on the root (a calibrated camera
   knows it); the scores below do not depend on heading anyway.

The ``lifted`` rows are the keypoint model's own error, with no robot: the lifted performer's
segments against the truth's, each in its own body frame, at the same 10 fps.

Scores as eval-robot's pipeline column (robot_retarget.evaluation.robot): per evaluation
frame (10 fps) the angle between each of the 9 human and robot segment directions (upper arms,
forearms, thighs, shins, torso) in the body frame, the robot on its trajectory's floating base
(its trunk follows the lifted performer's), averaged over
segments and frames weighted by clip duration; joint-limit and joint-speed violations over
every control frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.robot.metrics import segment_angles, trajectory_stats
from robot_retarget.evaluation.robot.runner import PipelineFn, PipelineRun, pipeline_runner
from robot_retarget.evaluation.robot.segments import RobotBodyModel, human_body_points
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.lift import lift_keypoints
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.keypoints.synthetic import EstimatorNoise, render_keypoints
from robot_retarget.keypoints.virtual_camera import VirtualCamera, heading_quat
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime

ELEVATIONS_DEG = (0.0, 15.0, 30.0)
AZIMUTHS_DEG = (45.0, 135.0, 225.0, 315.0)
CAMERA_FPS = 30.0
INPUTS = ("3d", "2d clip", "2d stream")


@dataclass
class InputScore:
    """Duration-weighted sums for one input kind (and view elevation)."""

    direction_deg_weighted: float = 0.0
    limb_deg_weighted: float = 0.0
    seconds: float = 0.0
    limit_violations: int = 0
    speed_violations: int = 0
    runs: int = 0

    def add(
        self, direction_deg: float, limb_deg: float, seconds: float, lim: int, spd: int
    ) -> None:
        self.direction_deg_weighted += direction_deg * seconds
        self.limb_deg_weighted += limb_deg * seconds
        self.seconds += seconds
        self.limit_violations += lim
        self.speed_violations += spd
        self.runs += 1

    @property
    def direction_deg(self) -> float:
        return self.direction_deg_weighted / max(self.seconds, 1e-12)

    @property
    def limb_deg(self) -> float:
        return self.limb_deg_weighted / max(self.seconds, 1e-12)


@dataclass
class Eval2DReport:
    robot: str
    model: str
    keypoint_model: str
    clips: int
    image_planes: bool = True
    rows: dict[str, InputScore] = field(default_factory=dict)  # "3d" | "2d clip @ 15°" …


def _camera(elevation_deg: float, azimuth_deg: float) -> VirtualCamera:
    return VirtualCamera(math.radians(azimuth_deg), math.radians(elevation_deg), 5.0, 1100.0)


def keypoints_of(
    motion: HumanMotion, camera: VirtualCamera, rng: np.random.Generator, noise: EstimatorNoise
) -> KeypointSequence:
    """``motion`` seen by ``camera`` at 30 fps as an estimator would report it."""
    cam_motion = motion.resample(CAMERA_FPS)
    px, conf, valid = render_keypoints(
        cam_motion.positions(), cam_motion.global_quats(), motion.height_m, camera, rng, noise
    )
    return KeypointSequence(  # the image size is known to whoever has the video
        px, conf, valid, CAMERA_FPS, source=str(motion.source_path), image_size=camera.image_size
    )


def world_heading(lifted: HumanMotion, camera: VirtualCamera) -> HumanMotion:
    """The lifted motion with the camera's azimuth turned back on its root rotation."""
    q = np.array(lifted.local_quats)
    q[:, 0] = quat.mul(quat.conjugate(heading_quat(camera.azimuth_rad)), q[:, 0])
    return HumanMotion(lifted.skeleton, q, lifted.root_pos, lifted.fps, lifted.source_path)


class Scorer:
    """Direction errors and violations of a pipeline run against a ground-truth motion."""

    def __init__(self, config: RobotConfig, eval_fps: float = 10.0) -> None:
        self.config = config
        self.body = RobotBodyModel(config)
        self.rate = float(config.control_rate_hz)
        self.eval_fps = eval_fps
        self.stride = max(1, round(self.rate / eval_fps))

    def score(
        self, truth: HumanMotion, q: FloatArray, root_quat: FloatArray | None = None
    ) -> tuple[float, float, float, int, int]:
        """(direction °, limb direction °, seconds, limit violations, speed violations) of joint
        angles ``q`` (T, J); with ``root_quat`` (T, 4) (a trajectory's floating base) the robot
        stands on it, as eval-robot scores the pipeline, else upright."""
        human = truth.resample(self.rate)
        pos = human.positions()
        n = min(pos.shape[0], q.shape[0])
        idx = np.arange(0, n, self.stride)
        base = None if root_quat is None else quat.to_matrix(np.asarray(root_quat)[idx])
        robot = self.body.body_points(q[idx], base)
        ang = np.degrees(segment_angles(human_body_points(pos[idx]), robot))
        stats = trajectory_stats(self.config, q[:n], self.rate)
        return (
            float(ang.mean()),
            float(ang[:, :8].mean()),
            n / self.rate,
            stats.limit_violations,
            stats.speed_violations,
        )

    def score_lifted(
        self, truth: HumanMotion, lifted: HumanMotion
    ) -> tuple[float, float, float, int, int]:
        """The keypoint model's own error: the lifted performer's segments against the truth's,
        each in its own body frame, at the evaluation rate (no robot, so no violations)."""
        rate = float(lifted.fps)
        stride = max(1, round(rate / self.eval_fps))
        truth_pos = truth.resample(rate).positions()
        lifted_pos = lifted.positions()
        n = min(truth_pos.shape[0], lifted_pos.shape[0])
        ang = np.degrees(
            segment_angles(
                human_body_points(truth_pos[:n:stride]), human_body_points(lifted_pos[:n:stride])
            )
        )
        return float(ang.mean()), float(ang[:, :8].mean()), n / rate, 0, 0

    def score_run(
        self, truth: HumanMotion, run: PipelineRun
    ) -> tuple[float, float, float, int, int]:
        """:meth:`score` of a pipeline run, on its own floating base."""
        return self.score(truth, run.q, run.root_quat)


def evaluate_2d(
    config: RobotConfig,
    clips: Sequence[tuple[str, Path]],
    model: str,
    keypoint_model: Agnostic2DRuntime,
    *,
    clip_keypoint_model: Agnostic2DRuntime | None = None,
    max_frames: int | None = None,
    noise: EstimatorNoise | None = None,
    seed: int = 0,
    pipeline: PipelineFn | None = None,
    stream_pipeline: PipelineFn | None = None,
    image_planes: bool = True,
    progress: Callable[[str], None] | None = None,
) -> Eval2DReport:
    """Score every clip from 3D and from 2D through every held-out view (module docstring);
    ``keypoint_model`` lifts the ``stream`` rows, ``clip_keypoint_model`` (if given, else the
    same) the ``clip`` rows; ``image_planes`` as ``convert`` and ``stream`` (keypoints.lift).
    ``pipeline`` runs the 3D and clip rows (as ``convert``), ``stream_pipeline`` the stream
    rows (default: ``pipeline`` when given, else the shipped pipeline with each limb in its first
    frame's branch, as ``stream`` cannot see ahead)."""
    run = pipeline or pipeline_runner(config, model)
    # The stream rows as stream runs them: no look at the whole clip for the limbs' branches.
    if stream_pipeline is None:  # a caller's own pipeline runs every row
        stream_pipeline = pipeline or pipeline_runner(config, model, whole_clip_branches=False)
    runs = {False: run, True: stream_pipeline}
    scorer = Scorer(config)
    noise = noise or EstimatorNoise()
    lifters = {True: keypoint_model, False: clip_keypoint_model or keypoint_model}
    names = dict.fromkeys(m.name for m in (lifters[False], lifters[True]))
    report = Eval2DReport(config.name, model, " / ".join(names), len(clips), image_planes)
    rows = report.rows
    for k, (name, path) in enumerate(clips):
        truth = load_motion(path, max_frames=max_frames)
        rows.setdefault("3d", InputScore()).add(*scorer.score_run(truth, run(truth)))
        for elevation in ELEVATIONS_DEG:
            for azimuth in AZIMUTHS_DEG:
                cam = _camera(elevation, azimuth)
                rng = np.random.default_rng([seed, k, int(elevation), int(azimuth)])
                seq = keypoints_of(truth, cam, rng, noise)
                for causal, label in ((False, "2d clip"), (True, "2d stream")):
                    lifter = lifters[causal]
                    lifted = lift_keypoints(seq, lifter, causal=causal, image_planes=image_planes)
                    lifted = world_heading(lifted, cam)
                    own = scorer.score_lifted(truth, lifted)
                    rows.setdefault(f"lifted, {label[3:]}", InputScore()).add(*own)
                    scores = scorer.score_run(truth, runs[causal](lifted))
                    rows.setdefault(f"{label} @ {elevation:g}°", InputScore()).add(*scores)
                    rows.setdefault(label, InputScore()).add(*scores)
        if progress is not None:
            progress(name)
    return report


def markdown_2d(report: Eval2DReport) -> str:
    """The report as a markdown table (rows: input, then per view elevation)."""
    base = report.rows["3d"].direction_deg
    lines = [
        f"eval-robot --input 2d: {report.robot}, model {report.model}, keypoint model "
        f"{report.keypoint_model}, {report.clips} clips × {len(ELEVATIONS_DEG) * len(AZIMUTHS_DEG)}"
        " views" + ("" if report.image_planes else ", without the image's planes"),
        "",
        "| input | direction error, mean (°) | vs 3D (°) | limb direction error (°) | "
        "limit violations | speed violations |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    order = ["3d"] + [
        key
        for label in ("2d clip", "2d stream")
        for key in (label, *(f"{label} @ {e:g}°" for e in ELEVATIONS_DEG))
    ]
    for key in order:
        r = report.rows[key]
        lines.append(
            f"| {key} | {r.direction_deg:.2f} | {r.direction_deg - base:+.2f} | "
            f"{r.limb_deg:.2f} | {r.limit_violations} | {r.speed_violations} |"
        )
    for key in ("lifted, clip", "lifted, stream"):  # no robot: no comparison, no violations
        if key in report.rows:
            r = report.rows[key]
            lines.append(f"| {key} | {r.direction_deg:.2f} | — | {r.limb_deg:.2f} | — | — |")
    return "\n".join(lines)
