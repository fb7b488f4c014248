"""Score a robot on live input: a (corrupted) sender through the real control loop.

A :class:`~robot_retarget.evaluation.live_corruption.CorruptedStream` is delivered as a UDP
positions sender would be — tracker faults undone and positions solved to rotations by the live
source's own :class:`~robot_retarget.sources.position_cleanup.LivePositions`, frames at their sender
times, silence where frames are missing — into the :class:`ControlLoop` (interpolation,
watchdog, ramp, optimizer, safety layer) on simulated time, in front of the kinematic
simulator. The commands the loop sent are then scored against the CLEAN performer at the clip
time each command played: segment direction error (eval-robot's measure) and jerk. The robot's
segment directions are kept, so that two runs of one clip can be compared with each other
(:func:`deviation_deg`: how far corrupted input moved the robot from where clean input put it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import InvalidMotionError
from robot_retarget.evaluation.live_corruption import CorruptedStream
from robot_retarget.evaluation.robot.metrics import segment_angles
from robot_retarget.evaluation.robot.segments import BodyPoints, RobotBodyModel, human_body_points
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.pipeline.floating_base import base_rotations
from robot_retarget.pipeline.input_filter import OneEuroSettings
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings, Mode
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.sim.backend import SimBackend
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.skeleton.trunk import trunk_frames_of_positions
from robot_retarget.sources.base import MotionSource, SourceFrame, SourceStats
from robot_retarget.sources.position_cleanup import LivePositions


class _SimClock:
    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def sleep(self, dt_s: float) -> None:
        self.t += max(dt_s, 0.0)


class StreamSource(MotionSource):
    """Delivers a :class:`CorruptedStream` at its sender times, polled on the loop's clock."""

    def __init__(
        self,
        stream: CorruptedStream,
        skeleton: Skeleton,
        fps: float,
        *,
        clean_positions: bool = True,
    ) -> None:
        self.stream = stream
        self._skeleton = skeleton
        self._fps = fps
        self._positions = LivePositions(skeleton, clean=clean_positions)
        self.stats = SourceStats()
        self._t0: float | None = None
        self._next = 0

    @property
    def skeleton(self) -> Skeleton:
        return self._skeleton

    @property
    def nominal_fps(self) -> float:
        return self._fps

    @property
    def finished(self) -> bool:
        return self._next >= len(self.stream.t_s)

    def start(self) -> None:
        self._t0, self._next = None, 0
        self._positions.reset()

    def stop(self) -> None:
        pass

    def poll(self, now_s: float) -> list[SourceFrame]:
        if self._t0 is None:
            self._t0 = now_s
        out = []
        while self._next < len(self.stream.t_s):
            t = float(self.stream.t_s[self._next])
            if self._t0 + t > now_s:
                break
            local, root = self._positions(self.stream.positions[self._next], t)
            out.append(SourceFrame(local, root, t, self._next, self._t0 + t))
            self._next += 1
        self.stats.received += len(out)
        self.stats.accepted += len(out)
        return out


@dataclass(frozen=True)
class LiveScore:
    """Mean segment direction error (°) and mean |jerk| (rad/s³) of the tracked commands
    played after ``settle_s``; ``commands`` scored. ``play_t_s`` (T,): the clip time each
    scored command played; ``robot``: the robot's segments then, as they were scored."""

    direction_deg: float
    jerk_rad_s3: float
    commands: int
    play_t_s: FloatArray
    robot: BodyPoints


def deviation_deg(run: LiveScore, reference: LiveScore) -> float:
    """Mean angle (°) between ``run``'s robot segments and ``reference``'s at the same clip
    time (each command against the reference command played nearest to it): how far the
    robot moved from the reference run, whatever the performer did. Unlike the rise of the
    direction error it does not depend on how far the reference itself is from the performer
    (noise added to a large error can even shrink it)."""
    ref_t, t = reference.play_t_s, run.play_t_s
    if len(ref_t) == 0 or len(t) == 0:
        raise ValueError("deviation_deg needs two runs with scored commands")
    after = np.clip(np.searchsorted(ref_t, t), 0, len(ref_t) - 1)
    before = np.maximum(after - 1, 0)
    nearest = np.where(np.abs(ref_t[before] - t) < np.abs(ref_t[after] - t), before, after)
    ref = reference.robot
    matched = BodyPoints(ref.directions[nearest], ref.end_effectors[nearest])
    return float(np.degrees(segment_angles(run.robot, matched).mean()))


def score_live(
    step: RetargetStep,
    clean: HumanMotion,
    stream: CorruptedStream,
    *,
    settle_s: float = 1.0,
    body: RobotBodyModel | None = None,
    input_filter: OneEuroSettings | None = None,
    clean_positions: bool = True,
) -> LiveScore:
    """Run ``stream`` through the loop (clip rate ``clean.fps`` as the sender's nominal rate)
    and score the commands against ``clean``; ``clean_positions=False``: the source solves
    the positions as sent (no cleanup of frozen joints, swapped limbs and jitter)."""
    if clean.num_frames / clean.fps <= settle_s:
        need = math.floor(settle_s * clean.fps) + 1
        raise InvalidMotionError(
            f"the clip is {clean.num_frames} frames ({clean.num_frames / clean.fps:.2f} s at "
            f"{clean.fps:g} fps): the live runs are scored after their first {settle_s:g} s, so "
            f"it must be longer (with --max-frames, at least {need})"
        )
    config = step.config
    clock = _SimClock()
    # Join the motion at once: the ramp is the same for every kind and is not what is scored.
    settings = LoopSettings(ramp_speed_fraction=1.0, ramp_min_s=0.0, input_filter=input_filter)
    source = StreamSource(stream, clean.skeleton, clean.fps, clean_positions=clean_positions)
    loop = ControlLoop(
        step, source, SimBackend(config, clock=clock.now), settings, record=True,
        clock=clock.now, sleep=clock.sleep,
    )  # fmt: skip
    result = loop.run()
    played = [e for e in result.log if e.mode is not Mode.STOPPING and e.play_t_s >= settle_s]
    if not played:
        raise InvalidMotionError(f"no command played after {settle_s} s: the clip is too short")
    q = np.array([e.q for e in played])
    t = np.array([e.play_t_s for e in played])
    frames = np.clip(np.rint(t * clean.fps).astype(int), 0, clean.num_frames - 1)
    positions = clean.positions()[frames]
    human = human_body_points(positions)
    model = body or RobotBodyModel(config)
    # A robot on its feet leans its trunk with its legs, as the performer does: it is scored on
    # a base that follows the performer's trunk (the frame the live targets are solved in).
    world = base_rotations(config, trunk_frames_of_positions(positions))
    robot = model.body_points(q, world)
    angles = segment_angles(human, robot)
    period = loop.period_s
    third = np.diff(q, n=3, axis=0)
    jerk = float(np.mean(np.abs(third)) / period**3) if third.size else 0.0
    return LiveScore(float(np.degrees(angles.mean())), jerk, len(q), t, robot)
