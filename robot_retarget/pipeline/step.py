"""The per-frame retargeting step shared by convert and stream (one code path).

human frame → network (online step, causal) → optimizer targets → Retargeter.solve (joint and
velocity limits) → a :class:`StepOutput`. The safety layer and the backend (a servo bus, the
simulator or a trajectory file) come after it, in the caller.
"""

from __future__ import annotations

import os
import time
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import InvalidMotionError, SolveError
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.optimize import Retargeter, SolveResult
from robot_retarget.optimize.live_frame import LiveFrameSolver
from robot_retarget.optimize.targets import FrameTargetBuilder, FrameTargets, check_dt
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import as_robot_config
from robot_retarget.runtime.loader import check_foot_lock, load_runtime_model, online_retargeter
from robot_retarget.runtime.model import OnlineStep, RuntimeModel
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.wire_sanity import WireSanity

if TYPE_CHECKING:
    from robot_retarget.nn.inference import LoadedModel


@dataclass(frozen=True)
class StepOutput:
    """One frame's result. ``q`` (J,) rad is inside every limit (the optimizer checked it);
    ``root_pos`` (3,) m and ``root_quat`` (4,) are the retargeted root (canonical axes, Y up);
    ``trunk_frame`` (3, 3) the retargeted pose's trunk frame the joint angles were solved in
    (columns forward, left, up, canonical axes: the floating base's orientation);
    ``times_s`` are the seconds spent in (network, targets, solve)."""

    q: FloatArray
    root_pos: FloatArray
    root_quat: FloatArray
    trunk_frame: FloatArray
    solve: SolveResult
    times_s: tuple[float, float, float]


@dataclass
class StepStats:
    frames: int = 0
    fallbacks: int = 0
    max_iter: int = 0


class RetargetStep:
    """Network + optimizer for one robot and one performer skeleton.

    Build the Retargeter once per robot (its JIT solver is compiled and cached) and pass it in;
    :meth:`set_source` switches performers (e.g. the next clip of a folder) without rebuilding.
    """

    def __init__(
        self,
        config: RobotConfig | str | os.PathLike[str],
        model: RuntimeModel | LoadedModel | str,
        source_skeleton: Skeleton | HumanMotion,
        *,
        retargeter: Retargeter | None = None,
        rate_hz: float | None = None,
        frame_program: bool = True,
        foot_lock: bool = False,
    ) -> None:
        config = as_robot_config(config)
        self.config = config
        # Warn of frames whose quaternions look x-y-z-w (the control loop's sources tell their
        # senders' conventions themselves, and turn this off).
        self.warn_conventions = True
        # The residual network's foot lock holds planted feet on its own output skeleton; on
        # the robot it costs direction error and jerk (cross-validated, README "Cross-validated
        # on the robot"), so the robot path leaves it out unless asked (--foot-lock).
        self.foot_lock = foot_lock
        # The rate frames arrive at (default: the config's control rate): the network's foot
        # lock turns a frame's displacement into a speed with it.
        self.rate_hz = float(rate_hz) if rate_hz is not None else config.control_rate_hz
        # A name or path: the numpy runtime when there is one (no torch), else torch.
        self.model = load_runtime_model(model) if isinstance(model, str) else model
        check_foot_lock(self.model, foot_lock=foot_lock)  # before the solver is built
        self.robot_skeleton = robot_canonical_skeleton(config)
        self.retargeter = retargeter if retargeter is not None else Retargeter(config)
        # Per-skeleton constants of the targets, computed once (the per-frame path).
        self.target_builder = FrameTargetBuilder(
            self.retargeter.problem,
            self.robot_skeleton,
            level_feet=self.retargeter.settings.level_feet,
        )
        # Targets, parameters and velocity box of a frame in one compiled call; False: the
        # numpy targets and writers (the benchmarks' reference).
        self.live = LiveFrameSolver(self.retargeter, self.target_builder) if frame_program else None
        self.stats = StepStats()
        # Per limb, the start whose optimum a settle takes (None: the best; convert's
        # whole-clip branch choice sets it, robot_retarget.pipeline.limb_branch_choice).
        self.settle_branches: tuple[int | None, ...] | None = None
        self.set_source(source_skeleton)

    def set_source(self, source_skeleton: Skeleton | HumanMotion) -> None:
        """A new performer: fresh network state for their rest offsets (and root track); a
        motion stands for its skeleton.

        Models with a numpy runtime (:mod:`robot_retarget.runtime`) run without torch; the
        others step through torch; the same numbers either way (tested)."""
        if isinstance(source_skeleton, HumanMotion):
            source_skeleton = source_skeleton.skeleton
        if not isinstance(source_skeleton, Skeleton):
            raise InvalidMotionError(
                "the performer is a Skeleton (a HumanMotion's .skeleton, or "
                f"robot_retarget.skeleton.canonical.default_canonical_skeleton()), got "
                f"{type(source_skeleton).__name__}"
            )
        self.online: OnlineStep = online_retargeter(
            self.model,
            source_skeleton.offsets,
            self.robot_skeleton.offsets,
            frame_rate_hz=self.rate_hz,
            foot_lock=self.foot_lock,
        )
        self._root_glitches = RootGlitches()
        self._source_joints = len(source_skeleton.names)
        self._conventions = WireSanity()  # a caller's quaternions x-y-z-w, warned once
        self._t_s = 0.0

    def warm_up(self, frames: int = 3) -> None:
        """A few network steps on the rest pose (the first torch call is slow), then a reset
        of the network's state; call before real time."""
        rest = np.zeros((len(self.robot_skeleton.names), 4))
        rest[:, 0] = 1.0
        for _ in range(frames):
            self.online.step(rest, np.zeros(3))
        self.online.reset()

    def reset(self, q_start: npt.ArrayLike | None = None) -> None:
        """Start a new sequence at ``q_start`` (default: the robot's init pose)."""
        self.online.reset()
        self.retargeter.reset(q_start)
        self.stats = StepStats()
        self._root_glitches = RootGlitches()
        self._conventions = WireSanity()
        self._t_s = 0.0

    def __call__(
        self,
        local_quats: npt.ArrayLike,
        root_pos: npt.ArrayLike,
        dt_s: float,
        *,
        q_prev: npt.ArrayLike | None = None,
        settle: bool = False,
    ) -> StepOutput:
        """Retarget one human frame; ``q_prev`` overrides the last command (velocity box).

        ``settle``: solve this frame to its optimum with no velocity limit
        (:meth:`Retargeter.settle`), the first frame of a sequence that does not have to start
        where the robot is."""
        t0 = time.perf_counter()
        if settle and q_prev is not None:
            raise InvalidMotionError("settle starts a sequence: it takes no q_prev")
        dt = _check_frame_interval(dt_s)
        local_quats, root_pos = _checked_frame(local_quats, root_pos)
        if local_quats.shape[0] != self._source_joints:
            raise InvalidMotionError(
                f"local_quats has {local_quats.shape[0]} rows, the performer's skeleton "
                f"{self._source_joints} joints (the canonical 22 in the order of "
                "robot_retarget.skeleton.canonical.CANONICAL_JOINTS, unless set_source gave "
                "another); the frame is refused"
            )
        self._t_s += dt
        tell = (
            self._conventions.rotations(local_quats, self._t_s) if self.warn_conventions else None
        )
        if tell is not None:
            warnings.warn(QUATERNION_ORDER_WARNING, ConventionWarning, stacklevel=2)
        root_pos = self._root_glitches(root_pos, dt_s)
        quats, root = self.online.step(local_quats, root_pos)
        t1 = time.perf_counter()
        if not settle and self.live is not None and self.live.write(quats, dt_s, q_prev=q_prev):
            t2 = time.perf_counter()
            result = self.retargeter.solve_written()
            trunk = self.live.trunk_frame()
        else:  # the first frame of a sequence, or a degenerate one: the numpy path
            targets = self.target_builder(quats)
            t2 = time.perf_counter()
            if settle:
                result = self.retargeter.settle(targets, self.settle_branches)
            else:
                result = self.retargeter.solve(targets, dt_s, q_prev=q_prev)
            trunk = _trunk_frame(targets)
        t3 = time.perf_counter()
        self.stats.frames += 1
        self.stats.fallbacks += int(result.used_fallback)
        # Solves stopped at the iteration cap; those stopped at the step tolerance
        # (retarget.step_tol_ticks) count as converged, not here.
        self.stats.max_iter += int(result.status.value == "max_iter")
        return StepOutput(
            q=np.asarray(result.q, dtype=np.float64),
            root_pos=np.asarray(root, dtype=np.float64),
            root_quat=np.asarray(quats[0], dtype=np.float64),
            trunk_frame=trunk,
            solve=result,
            times_s=(t1 - t0, t2 - t1, t3 - t2),
        )


class ConventionWarning(UserWarning):
    """Frames that look sent with another convention than the API's (quaternions w-x-y-z)."""


QUATERNION_ORDER_WARNING = (
    "RetargetStep: for a second most local rotations have |w| < 0.5 (turned more than 120° "
    "from the rest pose): are the quaternions x-y-z-w (scipy's Rotation.as_quat())? They are "
    "w-x-y-z, scalar first, each joint's rotation from the canonical rest pose "
    "(robot_retarget.skeleton.canonical)"
)

MAX_DT_S = 1.0
"""The longest time between two frames a step takes (frame rates below 1 fps are refused
everywhere): a longer one is almost always milliseconds given as seconds, and its velocity box
would let the joints move that many seconds' worth at once (4.9x a joint's limit at 8.0)."""


def _check_frame_interval(dt_s: float) -> float:
    """``dt_s`` as a finite positive number of seconds up to :data:`MAX_DT_S`, else a one-line
    SolveError saying what to pass; checked before anything of the frame is taken in."""
    dt = check_dt(dt_s)
    if dt > MAX_DT_S:
        raise SolveError(
            f"dt_s is {dt_s!r} s, more than {MAX_DT_S:g} s between two frames; it is in seconds "
            f"(milliseconds? then pass {dt / 1000.0:g}); no command was produced"
        )
    return dt


def _trunk_frame(targets: FrameTargets) -> FloatArray:
    if targets.trunk_frame is None:  # every builder sets it; a custom one may not
        raise ValueError("the step's target builder gave no trunk frame")
    return targets.trunk_frame


MAX_ROOT_SPEED_M_S = 30.0
"""A root that moves faster than this between two frames is a tracker's glitch, not a
performer (a sprinter peaks near 12 m/s): the jump is taken out of the root track."""
_MIN_JUMP_M = 0.05  # shorter jumps are never glitches, however short the frame interval
_UNIT_TOL = 1e-3  # |norm - 1| of a rotation quaternion beyond which it is no rotation


class RootGlitches:
    """The root as the network sees it: the performer's, less every jump faster than
    :data:`MAX_ROOT_SPEED_M_S` (a tracker that loses and re-finds the root, a sender restarted
    elsewhere). The network integrates root velocities, so one glitch would otherwise shift
    the root it reports for good (a 50 m jump and back left 4 cm; one frame at 10^6 m, km)."""

    def __init__(self) -> None:
        self._last: FloatArray | None = None
        self._shift = np.zeros(3)

    def __call__(self, root: FloatArray, dt_s: float) -> FloatArray:
        last, self._last = self._last, root.copy()
        if last is not None:
            jump = float(np.linalg.norm(root - last))
            if jump > _MIN_JUMP_M and jump > MAX_ROOT_SPEED_M_S * max(float(dt_s), 0.0):
                self._shift -= root - last
        return np.asarray(root + self._shift, dtype=np.float64)


def _checked_frame(
    local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """The frame as arrays, refused before it reaches the network: a NaN taken into its state
    (its history of frames) would make every later frame fail too."""
    quats = np.asarray(local_quats, dtype=np.float64)
    root = np.asarray(root_pos, dtype=np.float64)
    if quats.ndim != 2 or quats.shape[1] != 4:
        raise InvalidMotionError(
            f"local_quats must be (joints, 4) rotations w-x-y-z, got {quats.shape}"
        )
    if root.shape != (3,):
        raise InvalidMotionError(f"root_pos must be (3,) metres, got {root.shape}")
    if not (np.isfinite(quats).all() and np.isfinite(root).all()):
        what = "local_quats" if not np.isfinite(quats).all() else "root_pos"
        raise InvalidMotionError(
            f"{what} holds NaN or infinite values; the frame is refused (nothing changed: the "
            "next good frame goes on from the last)"
        )
    off = np.abs(np.linalg.norm(quats, axis=1) - 1.0)
    if (off > _UNIT_TOL).any():
        j = int(np.argmax(off))
        raise InvalidMotionError(
            f"local_quats row {j} has norm {np.linalg.norm(quats[j]):.6g}: rotations are unit "
            "quaternions w-x-y-z; the frame is refused (nothing changed: the next good frame "
            "goes on from the last)"
        )
    return quats, root
