"""eval-robot: convert clips with the full pipeline and score them against two references.

Per clip (every ``.bvh`` of the validation subjects):

1. **pipeline** — :func:`run_pipeline` (``robot_retarget.pipeline.convert.convert_motion``:
   network → optimizer targets → Retargeter.solve → SafetyLayer), frame by frame at the robot's
   control rate, from the init pose, exactly as ``convert`` / ``stream`` do;
2. **gmr** — the GMR-style baseline (:mod:`.gmr_style`): per-frame differential IK of knee,
   ankle, elbow and wrist positions walked along the robot's own segment lengths, foot
   orientations and a posture task, 3 iterations per frame within the joint limits and the
   servos' speeds, at the same rate from the same init pose;
3. **baseline** — per-frame position IK (:mod:`robot_retarget.optimize.position_ik`) of elbows,
   hands, knees and ankles to the human's keypoints scaled to the robot's limbs, within the
   joint limits and velocity box, at the same rate from the same init pose;
4. **limit** — :mod:`robot_retarget.optimize.kinematic_limit` per evaluation frame, started
   from the other three methods' poses among others, so it is never worse than any of them.

Direction and end-effector errors are scored on evaluation frames: every ``stride``-th frame at
the control rate, ``stride = round(rate / eval_fps)`` (default 10 fps: every 12th frame at
OP3's 125 Hz) — the kinematic limit is a multi-start optimisation per frame, and motion changes
little within 0.1 s. ``settle_s`` leaves the first seconds out of those scores (every run
starts from the robot's init pose, a deep crouch for OP3, and needs ≈ 0.5 s at the servos' speed
to reach the performer's first pose; the limit has no speed limit). Speed, limit violations
and jerk use every frame. Per-clip means are
averaged weighted by clip duration; p95 is over all evaluation frames pooled. Kinematic-limit
solutions are cached on disk (keyed by their inputs).
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SourceError
from robot_retarget.evaluation.robot.gmr_style import GMRStyleIK
from robot_retarget.evaluation.robot.metrics import (
    TrajectoryStats,
    end_effector_errors,
    segment_angles,
    trajectory_stats,
)
from robot_retarget.evaluation.robot.references import (
    baseline_points,
    baseline_targets,
    limit_segments,
    robot_body_axes,
)
from robot_retarget.evaluation.robot.segments import (
    KINDS,
    SEGMENT_KIND,
    WORLD_UP,
    BodyPoints,
    RobotBodyModel,
    body_axes,
    human_body_points,
)
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.optimize.kinematic_limit import KinematicLimit
from robot_retarget.optimize.position_ik import PositionIK
from robot_retarget.pipeline.floating_base import (
    base_rotations,
    floating_base,
    foot_skate_m_s,
    planted_feet,
    planted_skate_m_s,
    swing_scuffs,
    trajectory_feet,
)
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.trunk import trunk_frames_of_positions

log = logging.getLogger(__name__)

METHODS = ("pipeline", "gmr", "baseline", "limit")
METHOD_LABELS = {
    "pipeline": "pipeline",
    "gmr": "GMR-style IK",
    "baseline": "position-IK baseline",
    "limit": "kinematic limit",
}
_CACHE_VERSION = "1"


@dataclass(frozen=True)
class EvalRobotSettings:
    """What eval-robot runs. ``stride`` (evaluation frames) overrides ``eval_fps``;
    ``max_frames`` keeps the first frames of each clip (at the file's rate)."""

    eval_fps: float = 10.0
    stride: int | None = None
    max_frames: int | None = None
    settle_s: float = 0.0  # direction / end-effector scores skip the first seconds of a clip
    random_starts: int = 4
    seed: int = 0
    cache_dir: Path | None = None  # None: no kinematic-limit cache


@dataclass(frozen=True)
class PipelineRun:
    """What the full pipeline produced for one clip."""

    q: FloatArray  # (T, J) at ``fps``
    fps: float
    fallbacks: int
    ms_per_frame: float
    # (T, 4) w-x-y-z: the base link's orientation in the Z-up world (the trajectory's floating
    # base); None scores the robot standing upright, as the baselines are.
    root_quat: FloatArray | None = None
    # (T, 3) m: the base link's position in that world; None: the feet are placed as the
    # baselines' are (floating_base on the performer's trunk frames).
    root_pos: FloatArray | None = None


@dataclass(frozen=True)
class MethodClip:
    """One method on one clip. ``angles`` (N, 9) rad and ``ee`` (N, 4) on evaluation frames;
    ``stats`` None for the kinematic limit (per-frame poses, not a trajectory);
    ``foot_skate_m_s``: how fast the robot's feet slide on the ground on its floating base
    (every frame; None for the limit); ``planted_skate_m_s``: the same for the feet the
    performer stands on only (a swing foot skimming the floor left out);
    ``swing_scuffs``: (scraping, all) single-support swing foot-frames, a scraping one's lifted
    foot within 1 cm of the floor (:func:`.floating_base.swing_scuffs`)."""

    angles: FloatArray
    ee: FloatArray
    stats: TrajectoryStats | None
    fallbacks: int
    ms_per_frame: float
    foot_skate_m_s: float | None = None
    planted_skate_m_s: float | None = None
    swing_scuffs: tuple[int, int] | None = None

    @property
    def swing_scuff_share(self) -> float | None:
        """The share of this clip's swing frames that scrape (None: none measured)."""
        if self.swing_scuffs is None or self.swing_scuffs[1] == 0:
            return None
        return self.swing_scuffs[0] / self.swing_scuffs[1]


@dataclass(frozen=True)
class ClipScores:
    """Every method on one clip, plus poses for the stick-figure strip."""

    name: str
    duration_s: float
    methods: Mapping[str, MethodClip]
    human_positions: FloatArray = field(repr=False)  # (N, 22, 3) evaluation frames
    robot_q: Mapping[str, FloatArray] = field(repr=False)  # method → (N, J)


@dataclass(frozen=True)
class MethodSummary:
    """Aggregates over clips (angles in degrees, end-effector errors in limb lengths)."""

    segment_mean_deg: Mapping[str, float]  # KINDS, "overall" and "limbs" (all but the torso)
    segment_p95_deg: float  # p95 of the per-frame mean angle
    ee_hands: float
    ee_feet: float
    ee_overall: float
    limit_violations: int | None
    speed_violations: int | None
    max_speed_rad_s: float | None
    jerk_rad_s3: float | None
    fallbacks: int | None
    ms_per_frame: float
    foot_skate_m_s: float | None = None
    planted_skate_m_s: float | None = None
    swing_scuff_share: float | None = None


@dataclass(frozen=True)
class EvalRobotReport:
    robot: str
    model: str
    clips: tuple[ClipScores, ...]
    summary: Mapping[str, MethodSummary]
    rate_hz: float
    stride: int
    eval_frames: int
    wall_s: float
    settle_s: float = 0.0


PipelineFn = Callable[[HumanMotion], PipelineRun]


def pipeline_runner(
    config: RobotConfig,
    model: str,
    *,
    foot_lock: bool = False,
    whole_clip_branches: bool = True,
    place_feet: bool | None = None,
) -> PipelineFn:
    """The full pipeline (network → optimizer → safety) as one function of a motion, as
    ``convert`` runs it; ``foot_lock``: run the network's foot lock (``--foot-lock``; off on the
    robot by default); ``whole_clip_branches`` False: each limb in the first frame's best
    branch, as ``stream`` runs it (robot_retarget.pipeline.limb_branch_choice);
    ``place_feet``: lift the swing feet and hold the feet in double support as ``convert``
    does (default: unless ``whole_clip_branches`` is False, since ``stream`` sends the feet as
    solved)."""
    place = whole_clip_branches if place_feet is None else place_feet
    from robot_retarget.pipeline.convert import convert_motion
    from robot_retarget.pipeline.step import RetargetStep

    step: RetargetStep | None = None

    def run(motion: HumanMotion) -> PipelineRun:
        nonlocal step
        if step is None:
            step = RetargetStep(config, model, motion.skeleton, foot_lock=foot_lock)
        result = convert_motion(
            motion,
            step,
            whole_clip_branches=whole_clip_branches,
            lift_swing_feet=place,
            hold_double_support=place,
        )
        traj = result.trajectory
        frame_ms = traj.frame_ms
        ms = (
            float(np.mean(frame_ms))
            if frame_ms is not None
            else result.wall_s * 1e3 / traj.num_frames
        )
        return PipelineRun(
            np.asarray(traj.q),
            traj.fps,
            result.fallbacks,
            ms,
            np.asarray(traj.root_quat),
            np.asarray(traj.root_pos),
        )

    return run


ORACLE_MODEL = "oracle"


def oracle_runner(config: RobotConfig) -> PipelineFn:
    """The pipeline with an ideal network: the optimizer's targets come from the human's own
    global positions and rotations (``targets_from_globals``), then Retargeter.solve and the
    SafetyLayer run as in ``convert``. Separates the optimizer's share of the error from the
    network's."""
    from robot_retarget.hardware.safety import SafetyLayer
    from robot_retarget.hardware.types import JointCommand
    from robot_retarget.optimize import Retargeter, targets_from_globals
    from robot_retarget.pipeline.recorder import RecordingBackend

    retargeter = Retargeter(config)

    def run(motion: HumanMotion) -> PipelineRun:
        rate = float(config.control_rate_hz)
        m = motion if abs(motion.fps - rate) < 1e-9 else motion.resample(rate)
        dt = 1.0 / rate
        targets = targets_from_globals(
            retargeter.problem,
            m.positions(),
            m.global_quats(),
            level_feet=retargeter.settings.level_feet,
        )
        safety = SafetyLayer(config, RecordingBackend(config), clock=None)  # a recording
        safety.connect()
        retargeter.reset(config.init_pose)
        q = np.empty((m.num_frames, config.num_joints))
        fallbacks = 0
        t0 = time.perf_counter()
        for t in range(m.num_frames):
            # The first frame at its optimum, as convert starts.
            result = (
                retargeter.settle(targets.frame(t))
                if t == 0
                else retargeter.solve(targets.frame(t), dt)
            )
            if t == 0:
                safety.reset(result.q)
            # Stamps 1 ppb apart more than dt, as convert does: the step bound is exactly v·dt.
            q[t] = safety.send(JointCommand(result.q, t * dt * (1.0 + 1e-9))).q
            fallbacks += int(result.used_fallback)
        ms = (time.perf_counter() - t0) * 1e3 / m.num_frames
        safety.disconnect()
        base = floating_base(config, m, q)  # the performer's trunk frames, as the targets'
        return PipelineRun(q, rate, fallbacks, ms, base.root_quat, base.root_pos)

    return run


class RobotEvaluator:
    """Scores clips for one robot: pipeline (given), GMR-style IK, position-IK baseline and
    kinematic limit (built here)."""

    def __init__(
        self,
        config: RobotConfig,
        pipeline: PipelineFn,
        settings: EvalRobotSettings | None = None,
    ) -> None:
        self.config = config
        self.pipeline = pipeline
        self.settings = settings or EvalRobotSettings()
        self.body = RobotBodyModel(config)
        frames = self.body.frames
        self.baseline = PositionIK(config, baseline_points(frames))
        self.gmr = GMRStyleIK(config, frames)
        self.limit = KinematicLimit(
            config,
            limit_segments(frames),
            robot_body_axes(config, frames),
            random_starts=self.settings.random_starts,
            seed=self.settings.seed,
        )
        self._upright_axes = robot_body_axes(config, frames)
        zero = np.zeros(config.num_joints)
        self._hips_root = RobotKinematics(config).frame_positions(zero, list(frames.hips))
        self.rate_hz = float(config.control_rate_hz)
        st = self.settings
        self.stride = st.stride or max(1, round(self.rate_hz / st.eval_fps))

    def score_motion(self, motion: HumanMotion, name: str) -> ClipScores:
        run = self.pipeline(motion)
        rate = run.fps
        human = motion if abs(motion.fps - rate) < 1e-9 else motion.resample(rate)
        pos = human.positions()
        n = min(pos.shape[0], run.q.shape[0])
        pos, q_pipe = pos[:n], run.q[:n]
        first = min(n - 1, math.ceil(self.settings.settle_s * rate - 1e-9))
        idx = np.arange(first, n, self.stride)
        h = human_body_points(pos[idx])
        dt = 1.0 / rate
        t0 = time.perf_counter()
        base = self.baseline.solve_clip(baseline_targets(self.config, pos), dt)
        base_ms = (time.perf_counter() - t0) * 1e3 / n
        t0 = time.perf_counter()
        gmr = self.gmr.solve_clip(self.gmr.targets(pos, human.global_quats()[:n]), dt)
        gmr_ms = (time.perf_counter() - t0) * 1e3 / n
        candidates = np.stack([q_pipe[idx], gmr.q[idx], base.q[idx]], axis=1)
        # The baselines and the limit stand on the performer's trunk frames, the pipeline on
        # its trajectory's own base (the network's trunk frames): every method's limbs and
        # torso are scored in the world, as a floating-base robot shows them.
        world = base_rotations(self.config, trunk_frames_of_positions(pos))
        pipe_world = world if run.root_quat is None else quat.to_matrix(run.root_quat[:n])
        limit_q, limit_ms = self._limit(h, candidates, world[idx])
        qs = {"pipeline": q_pipe[idx], "gmr": gmr.q[idx], "baseline": base.q[idx], "limit": limit_q}
        human_n = human if human.num_frames == n else human.frames(0, n)
        pipe_feet = (
            floating_base(self.config, human_n, q_pipe).feet
            if run.root_pos is None or run.root_quat is None
            else trajectory_feet(self.config, q_pipe, run.root_pos[:n], run.root_quat[:n])
        )
        methods = {
            "pipeline": self._method(
                h, q_pipe, idx, rate, run.fallbacks, run.ms_per_frame, pipe_world
            ),
            "gmr": self._method(h, gmr.q, idx, rate, 0, gmr_ms, world),
            "baseline": self._method(h, base.q, idx, rate, base.fallbacks, base_ms, world),
            "limit": self._method(h, limit_q, None, rate, 0, limit_ms, world[idx]),
        }
        # Feet on the ground, every frame: the pipeline on its trajectory's base, the
        # baselines on the base convert would give them (the performer's trunk frames).
        feet = {
            "pipeline": pipe_feet,
            "gmr": floating_base(self.config, human_n, gmr.q[:n]).feet,
            "baseline": floating_base(self.config, human_n, base.q[:n]).feet,
        }
        planted = planted_feet(self.config, pos, rate)  # pos: human_n's, at the run's rate
        methods = {
            m: dataclasses.replace(
                c,
                foot_skate_m_s=foot_skate_m_s(feet[m], rate),
                planted_skate_m_s=planted_skate_m_s(feet[m], rate, planted),
                swing_scuffs=swing_scuffs(self.config, feet[m], planted),
            )
            if m in feet
            else c
            for m, c in methods.items()
        }
        return ClipScores(name, n / rate, methods, pos[idx], qs)

    def _method(
        self,
        human: BodyPoints,
        q: FloatArray,
        idx: npt.NDArray[np.int64] | None,
        rate: float,
        fallbacks: int,
        ms: float,
        world: FloatArray | None = None,
    ) -> MethodClip:
        """Scores of joint angles ``q`` (T, J); with ``world`` (T, 3, 3) the base's orientation
        per frame the robot stands on that floating base, else upright."""
        sampled = q if idx is None else q[idx]
        rot = None if world is None else (world if idx is None else world[idx])
        robot = self.body.body_points(sampled, rot)
        stats = None if idx is None else trajectory_stats(self.config, q, rate)
        return MethodClip(
            segment_angles(human, robot), end_effector_errors(human, robot), stats, fallbacks, ms
        )

    def _limit(
        self, human: BodyPoints, candidates: FloatArray, world: FloatArray
    ) -> tuple[FloatArray, float]:
        """(poses (N, J), ms per evaluation frame) of the least direction error for a robot
        whose base has orientation ``world`` (N, 3, 3); from the disk cache when possible."""
        targets = self._limit_targets(human.directions, world)
        st = self.settings
        path = None
        if st.cache_dir is not None:
            h = hashlib.sha256()
            for part in (
                _CACHE_VERSION,
                self.config.name,
                repr(self.config.joints),
                repr(self.config.frames),
                repr((st.random_starts, st.seed)),
            ):
                h.update(part.encode())
            h.update(np.ascontiguousarray(targets).tobytes())
            h.update(np.ascontiguousarray(candidates).tobytes())
            path = st.cache_dir / f"limit-{h.hexdigest()[:24]}.npz"
            if path.is_file():
                with np.load(path) as z:
                    return np.asarray(z["q"]), float(z["ms"])
        t0 = time.perf_counter()
        result = self.limit.solve(targets, candidates)
        ms = (time.perf_counter() - t0) * 1e3 / max(1, candidates.shape[0])
        if path is not None:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                np.savez(path, q=result.q, ms=ms)
            except OSError as exc:  # a read-only cache only costs time next run
                log.warning("could not cache the kinematic limit at %s: %s", path, exc)
        return result.q, ms

    def _limit_targets(self, directions: FloatArray, world: FloatArray) -> FloatArray:
        """The human's body-frame directions (N, S, 3) as the limit's solver reads them (the
        upright robot's body frame, constant) for a robot whose base has orientation ``world``:
        d_body = A_t · R_t · v_root must meet h, so v_root must meet R_tᵀ A_tᵀ h."""
        hips = self._hips_root @ np.swapaxes(world, 1, 2)  # (N, 2, 3): R_t · p for each hip
        a = body_axes(hips[:, 0], hips[:, 1], WORLD_UP)  # (N, 3, 3) rows, world
        m = self._upright_axes @ np.swapaxes(world, 1, 2) @ np.swapaxes(a, 1, 2)
        return np.asarray(np.einsum("nij,nsj->nsi", m, directions), dtype=np.float64)


def summarize(clips: Sequence[ClipScores]) -> dict[str, MethodSummary]:
    """Duration-weighted means over clips, p95 over pooled evaluation frames, sums of counts."""
    if not clips:
        raise SourceError("no clips were scored; check --data and the subjects")
    w = np.array([c.duration_s for c in clips])
    w = w / w.sum()
    kind_idx = {k: [i for i, s in enumerate(SEGMENT_KIND) if s == k] for k in KINDS}
    limbs = [i for i, s in enumerate(SEGMENT_KIND) if s != "torso"]
    out = {}
    for m in METHODS:
        per = [c.methods[m] for c in clips]
        seg = {
            k: float(
                np.degrees(sum(wi * p.angles[:, ix].mean() for wi, p in zip(w, per, strict=True)))
            )
            for k, ix in kind_idx.items()
        }
        seg["overall"] = float(
            np.degrees(sum(wi * p.angles.mean() for wi, p in zip(w, per, strict=True)))
        )
        seg["limbs"] = float(
            np.degrees(sum(wi * p.angles[:, limbs].mean() for wi, p in zip(w, per, strict=True)))
        )
        pooled = np.concatenate([p.angles.mean(axis=1) for p in per])
        ee_h = float(sum(wi * p.ee[:, :2].mean() for wi, p in zip(w, per, strict=True)))
        ee_f = float(sum(wi * p.ee[:, 2:].mean() for wi, p in zip(w, per, strict=True)))
        stats = [p.stats for p in per]
        has = all(s is not None for s in stats)
        ss = [s for s in stats if s is not None]
        out[m] = MethodSummary(
            segment_mean_deg=seg,
            segment_p95_deg=float(np.degrees(np.percentile(pooled, 95))),
            ee_hands=ee_h,
            ee_feet=ee_f,
            ee_overall=0.5 * (ee_h + ee_f),
            limit_violations=sum(s.limit_violations for s in ss) if has else None,
            speed_violations=sum(s.speed_violations for s in ss) if has else None,
            max_speed_rad_s=max(s.max_speed_rad_s for s in ss) if has else None,
            jerk_rad_s3=float(sum(wi * s.jerk_rad_s3 for wi, s in zip(w, ss, strict=True)))
            if has
            else None,
            fallbacks=sum(p.fallbacks for p in per) if has else None,
            ms_per_frame=float(sum(wi * p.ms_per_frame for wi, p in zip(w, per, strict=True))),
            foot_skate_m_s=_weighted(w, [p.foot_skate_m_s for p in per]),
            # Clips where the performer never stands on a foot the robot has down say nothing.
            planted_skate_m_s=_weighted_present(w, [p.planted_skate_m_s for p in per]),
            # Pooled over swing frames: a clip with a few single-support frames counts as few.
            swing_scuff_share=_pooled_share([p.swing_scuffs for p in per]),
        )
    return out


def _weighted_present(w: FloatArray, values: Sequence[float | None]) -> float | None:
    """The ``w``-weighted mean of the clips that have a value, or None if none has."""
    present = [(wi, v) for wi, v in zip(w, values, strict=True) if v is not None]
    total = sum(wi for wi, _ in present)
    return float(sum(wi * v for wi, v in present) / total) if present and total > 0 else None


def _pooled_share(counts: Sequence[tuple[int, int] | None]) -> float | None:
    """Σ hits / Σ frames over the clips that have counts (None: no frames at all)."""
    present = [c for c in counts if c is not None]
    total = sum(n for _, n in present)
    return sum(k for k, _ in present) / total if total else None


def _weighted(w: FloatArray, values: Sequence[float | None]) -> float | None:
    """The ``w``-weighted mean of per-clip values, or None if a clip has none."""
    if any(v is None for v in values):
        return None
    return float(sum(wi * float(v or 0.0) for wi, v in zip(w, values, strict=True)))


def validation_clips(
    data_dir: str | Path, subjects: Sequence[str] | None = None
) -> list[tuple[str, Path]]:
    """(subject/clip name, path) of the BVH clips to score under ``data_dir``.

    ``subjects`` None (or the training split's default validation subjects, which the CLI
    passes when ``--val-subjects`` is not given): those subjects' clips when the folder holds
    any, else **every** clip — a folder that is not the training data (other performers, your
    own recordings) has no training split to respect. Subjects named otherwise must exist.
    """
    from robot_retarget.nn.dataset import DEFAULT_VALIDATION_SUBJECTS, find_clips, subject_of

    root = Path(data_dir)
    default = subjects is None or tuple(subjects) == DEFAULT_VALIDATION_SUBJECTS
    keep = set(DEFAULT_VALIDATION_SUBJECTS if subjects is None else subjects)
    clips = [(p.relative_to(root).as_posix(), p) for p in find_clips(root)]
    chosen = [(n, p) for n, p in clips if subject_of(p, root) in keep]
    if not chosen and default:
        log.info("no clips of the validation subjects %s under %s: scoring all %d clips",
                 sorted(keep), root, len(clips))  # fmt: skip
        return clips
    if not chosen:
        raise SourceError(
            f"no clips of subjects {sorted(keep)} under {root}; pass --val-subjects with "
            "subjects that exist there"
        )
    return chosen


def evaluate_robot(
    config: RobotConfig,
    clips: Sequence[tuple[str, Path]],
    pipeline: PipelineFn,
    settings: EvalRobotSettings | None = None,
    *,
    model_name: str = "",
    progress: Callable[[str], None] | None = None,
) -> EvalRobotReport:
    """Score every clip; see the module docstring."""
    t0 = time.perf_counter()
    ev = RobotEvaluator(config, pipeline, settings)
    scores = []
    for name, path in clips:
        motion = load_motion(path, max_frames=ev.settings.max_frames)
        scores.append(ev.score_motion(motion, name))
        if progress is not None:
            progress(name)
    return EvalRobotReport(
        robot=config.name,
        model=model_name,
        clips=tuple(scores),
        summary=summarize(scores),
        rate_hz=ev.rate_hz,
        stride=ev.stride,
        eval_frames=sum(c.methods["pipeline"].angles.shape[0] for c in scores),
        wall_s=time.perf_counter() - t0,
        settle_s=ev.settings.settle_s,
    )


def with_retarget_overrides(config: RobotConfig, overrides: Mapping[str, float]) -> RobotConfig:
    """The config with optimizer options replaced (for tuning runs; validated on use)."""
    return dataclasses.replace(config, retarget={**config.retarget, **overrides})
