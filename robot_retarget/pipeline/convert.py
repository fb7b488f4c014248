"""Offline conversion: a human clip → a robot trajectory, with the live path's per-frame step.

Each frame goes through exactly what ``stream`` sends to a servo: the network's online step,
the optimizer (Retargeter.solve, warm-started frame by frame) and the SafetyLayer, with the
file's frame period as the control period. The file starts at the clip's first frame solved
to its optimum (no catching up from the robot's init pose): the trajectory a stream joins at
the end of its ramp. We do not use Retargeter.solve_clip here (windows
solved jointly are 15–30 % smoother, see robot_retarget.optimize) so that a converted file and
a live stream of the same clip at the same rate give the same joint angles — with each limb in
its first frame's branch, as ``stream`` runs it (``whole_clip_branches`` False, the default
here, ``convert --stream-branches``); ``convert`` itself chooses each limb's branch on the whole
clip (robot_retarget.pipeline.limb_branch_choice). Every frame in the file is checked against
the joint limits and the velocity limits (from its first frame).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robot_retarget.hardware.safety import SafetyLayer
from robot_retarget.hardware.types import JointCommand
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.double_support import hold_double_support as hold_feet
from robot_retarget.pipeline.floating_base import FloatingBase, floating_base
from robot_retarget.pipeline.lead_in import lead_in, lead_in_base
from robot_retarget.pipeline.recorder import RecordingBackend
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.pipeline.swing_clearance import clear_swing_feet
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.model import OnlineStep

_LIMIT_TOL_RAD = 1e-9
# Command stamps 1 ppb apart more than dt: the safety layer then bounds each step by exactly
# v_max · dt (its min(Δt, period)), the optimizer's bound, instead of a rounded-down Δt that
# would "clip" 1e-14 rad off every step at the velocity limit.
_STAMP_STRETCH = 1.0 + 1e-9


@dataclass(frozen=True)
class LimitCheck:
    """Largest excess (rad) over the joint limits and over ``v_max · dt`` between frames."""

    position_excess_rad: float
    velocity_excess_rad: float

    @property
    def ok(self) -> bool:
        return max(self.position_excess_rad, self.velocity_excess_rad) <= _LIMIT_TOL_RAD


def check_limits(
    config: RobotConfig, q: npt.ArrayLike, dt_s: float, q_start: npt.ArrayLike | None = None
) -> LimitCheck:
    """Check a (T, J) trajectory against the config's position and velocity limits; steps are
    counted from ``q_start`` (where the robot was before the first row) when given, else
    between the rows only (a file that starts where its first row is). A value that is not a
    number exceeds every limit."""
    a = np.asarray(q, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        return LimitCheck(float("inf"), float("inf"))
    above = float(np.max(a - config.upper, initial=0.0))
    below = float(np.max(config.lower - a, initial=0.0))
    pos = max(0.0, above, below)
    if q_start is not None:
        a_from = np.vstack([np.asarray(q_start, dtype=np.float64)[None], a])
    else:
        a_from = a
    steps = np.abs(np.diff(a_from, axis=0))
    vel = max(0.0, float(np.max(steps - config.max_velocity * dt_s, initial=0.0)))
    # Within the tolerance is within the limit: no 2.8e-17 rad of float rounding reported.
    return LimitCheck(*(x if x > _LIMIT_TOL_RAD else 0.0 for x in (pos, vel)))


@dataclass(frozen=True)
class ClipResult:
    """A converted clip and what happened on the way."""

    trajectory: RobotTrajectory
    wall_s: float
    limits: LimitCheck
    safety_commands_clipped: int
    safety_joint_clips: int
    fallbacks: int
    lead_in_frames: int = 0  # of the trajectory's frames, the lead-in's (not solved)

    @property
    def frames(self) -> int:
        return self.trajectory.num_frames

    def __str__(self) -> str:
        """What convert prints for a clip: frames, time, limits, clips and fallbacks."""
        return clip_line(
            self.frames, self.lead_in_frames, self.wall_s, self.limits.ok,
            self.safety_commands_clipped, self.safety_joint_clips, self.fallbacks,
        )  # fmt: skip


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, in the plural unless it is one ("1 frame", "2 frames")."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def lead_in_part(frames: int) -> str:
    """How many of a clip's frames are its --lead-in's ("" for none)."""
    return f" ({frames} of them the lead-in's)" if frames else ""


def clip_line(
    frames: int,
    lead_in_frames: int,
    wall_s: float,
    limits_ok: bool,
    clipped_commands: int,
    clipped_joints: int,
    fallbacks: int,
) -> str:
    """One converted clip as convert prints it (the rate leaves the lead-in's frames out)."""
    solved = frames - lead_in_frames
    return (
        f"{counted(frames, 'frame')}{lead_in_part(lead_in_frames)}, {wall_s:.2f} s "
        f"({solved / max(wall_s, 1e-9):.0f} frames/s), limits "
        f"{'respected' if limits_ok else 'VIOLATED'}, safety clipped "
        f"{counted(clipped_commands, 'command')} ({counted(clipped_joints, 'joint value')}), "
        f"{counted(fallbacks, 'solver fallback')}"
    )


LEAD_IN_SPEED_FRACTION = 0.25
"""``--lead-in``'s speed, a share of each joint's velocity limit: the stream's ramp speed."""


def convert_motion(
    motion: HumanMotion,
    step: RetargetStep,
    *,
    fps: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    lead_in_speed_fraction: float | None = None,
    network: OnlineStep | None = None,
    whole_clip_branches: bool = False,
    lift_swing_feet: bool = True,
    hold_double_support: bool = True,
) -> ClipResult:
    """Retarget ``motion`` frame by frame at ``fps`` (default: the robot's control rate).

    ``lead_in_speed_fraction``: also prepend a move from the robot's init pose to the first
    frame at that fraction of each joint's velocity limit (the stream's ramp speed is 0.25),
    stamped before the clip: ``t0`` < 0, the clip itself still starts at t = 0 and is
    unchanged. Without it the file starts at the clip's first frame.

    ``whole_clip_branches``: choose each limb's branch on the whole clip
    (:mod:`robot_retarget.pipeline.limb_branch_choice`, what ``convert`` does); False keeps the
    first frame's best, as ``stream`` does.

    ``lift_swing_feet``: lift each swing foot as high as the performer's, turning only its
    ankle's pitch joint (:mod:`robot_retarget.pipeline.swing_clearance`); False leaves the
    feet as solved, as ``stream`` sends them (with ``whole_clip_branches`` and
    ``hold_double_support`` False as well, the file then matches a stream of the clip).

    ``hold_double_support``: where the performer stands on both feet, move the legs so that
    the feet do not slide against each other (:mod:`robot_retarget.pipeline.double_support`);
    False leaves them as solved (the base, pinned on their mean slip, lets each slide by half
    of what they slide against each other), as ``stream`` sends them.

    ``network``: the network step to use instead of the model's own (e.g. a
    :class:`~robot_retarget.pipeline.precomputed_step.PrecomputedStep` of the clip read on its
    own skeleton, at the output rate)."""
    config = step.config
    rate = float(fps) if fps is not None else config.control_rate_hz
    m = motion if abs(motion.fps - rate) < 1e-9 else motion.resample(rate)
    dt = 1.0 / rate
    # The file's frame period is its control period: the safety layer's step bound uses it.
    file_config = dataclasses.replace(config, control_rate_hz=rate)
    safety = SafetyLayer(file_config, RecordingBackend(config), clock=None)  # a recording
    safety.connect()
    step.set_source(m.skeleton)
    if network is not None:
        step.online = network
    t_start = time.perf_counter()  # the conversion's wall time: branch choice to the feet's hold
    try:
        step.settle_branches = None
        n = m.num_frames
        passes = 1  # the progress bar covers the branch choice's runs too
        if whole_clip_branches:
            from robot_retarget.pipeline.limb_branch_choice import STARTS, choose_branches

            passes += STARTS
            tick = None if progress is None else (lambda t: progress(t, passes * n))
            step.settle_branches = choose_branches(m, step, dt, tick)
        done = (passes - 1) * n
        step.reset(config.init_pose)
        q = np.empty((n, config.num_joints))
        root_pos = np.empty((0, 3))
        root_quat = np.empty((0, 4))
        trunk = np.empty((n, 3, 3))  # the frames the limbs were solved in: the base turns with them
        frame_ms = np.empty(n)
        for t in range(n):
            t0 = time.perf_counter()
            out = step(m.local_quats[t], m.root_pos[t], dt, settle=t == 0)
            if t == 0:
                safety.reset(out.q)  # the step bound starts at the first frame's optimum
            sent = safety.send(JointCommand(out.q, t * dt * _STAMP_STRETCH))
            frame_ms[t] = (time.perf_counter() - t0) * 1e3
            q[t] = sent.q
            trunk[t] = out.trunk_frame
            if progress is not None:
                progress(done + t + 1, passes * n)
    finally:
        step.settle_branches = None  # never left for the next clip (or a stream) to inherit
    safety.disconnect()
    # The base link's pose in the robot's world (Z up, x forward), feet on the ground, the swing
    # feet lifted as high as the performer's (only the ankles' pitch joints move), then the
    # feet held against each other where the performer stands on both (the legs' joints move;
    # after the lift, which tips a foot at the ends of its stance).
    base: FloatingBase | None = None
    if n and lift_swing_feet:
        q, base = clear_swing_feet(config, m, q, trunk_frames=trunk)
    elif n:
        base = floating_base(config, m, q, trunk_frames=trunk)
    if base is not None and hold_double_support:
        q, base = hold_feet(config, m, q, base, trunk_frames=trunk)
    wall = time.perf_counter() - t_start  # the solve, the lift and the hold
    pos = base.root_pos if base is not None else root_pos
    quat = base.root_quat if base is not None else root_quat
    t0 = 0.0
    k = 0
    limits = check_limits(config, q, dt)
    if lead_in_speed_fraction is not None and n:
        lead = lead_in(config, q[0], lead_in_speed_fraction * config.max_velocity * dt)
        k = len(lead)
        lead_pos, lead_quat = lead_in_base(config, lead, q[0], pos[0], quat[0])
        q = np.vstack([lead, q])
        pos = np.vstack([lead_pos, pos])
        quat = np.vstack([lead_quat, quat])
        frame_ms = np.concatenate([np.zeros(k), frame_ms])
        t0 = -k * dt
        limits = check_limits(config, q, dt, q_start=config.init_pose)
    traj = RobotTrajectory(
        joint_names=config.joint_names,
        q=q,
        fps=rate,
        root_pos=pos,
        root_quat=quat,
        t0=t0,
        frame_ms=frame_ms,
    )
    return ClipResult(
        trajectory=traj,
        wall_s=wall,
        limits=limits,
        safety_commands_clipped=safety.stats.commands_clipped,
        safety_joint_clips=safety.stats.position_clips + safety.stats.step_clips,
        fallbacks=step.stats.fallbacks,
        lead_in_frames=k,
    )


def output_paths(input_path: Path, out: Path, suffix: str) -> list[tuple[Path, Path]]:
    """(clip, output) pairs: one file, or every .bvh under a folder with its structure kept."""
    if input_path.is_dir():
        clips = sorted(p for p in input_path.rglob("*") if p.suffix.lower() == ".bvh")
        return [(c, out / c.relative_to(input_path).with_suffix(suffix)) for c in clips]
    return [(input_path, out)]
