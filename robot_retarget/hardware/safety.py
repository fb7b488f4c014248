"""The safety layer in front of every backend: whatever upstream produced, only commands inside
the joint limits and within ``v_max · dt`` of the previous command reach the servos.

NaN/inf or a wrong shape raise :class:`UnsafeCommandError` and nothing is sent. Position and
step clipping are counted per joint and summarised by :meth:`SafetyLayer.report`.
``dt`` is the time since the previous command (from ``JointCommand.t_s``), never more than
the config's control period, so jumping timestamps cannot loosen the step bound; a command
whose time does not come after the previous one's is refused (UnsafeCommandError). Stamps are
the caller's word, so the layer also keeps time itself (``clock``, the wall clock unless the
caller drives a simulated or recorded timeline): a
:class:`~robot_retarget.hardware.velocity_budget.VelocityBudget` up to
:data:`CLOCK_BUDGET_PERIODS` periods deep. Commands sent faster than their stamps say (a
trajectory played in a loop without waiting) are bounded by the time that really passed; a
loop at its rate never notices (a late tick and the early one after it fit in the budget). For a
backend that rounds commands (a servo's position tick, ``JointBackend.position_quantum_rad``)
the command returned is the one it will write, on its grid and within ``v_max · dt`` of what
it wrote last (the nearest tick could be one too far).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import HardwareError
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.hardware.types import JointCommand, JointState
from robot_retarget.hardware.velocity_budget import VelocityBudget
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import as_robot_config
from robot_retarget.robot.pose_check import beyond_a_turn


class UnsafeCommandError(HardwareError):
    """A command that cannot be made safe (NaN, inf, wrong shape); nothing was sent."""

    def __init__(self, message: str, *, joints: tuple[str, ...] = ()) -> None:
        self.joints = joints
        super().__init__(message)


@dataclass
class ClipStats:
    """What the safety layer changed. Counts are joint-frames (one joint in one command)."""

    commands: int = 0
    commands_clipped: int = 0
    position_clips: int = 0
    step_clips: int = 0
    # Joint-frames the clock budget held back further than the stamps' step bound would have
    # (commands sent faster than real time, or a late loop catching up).
    clock_clips: int = 0
    max_position_excess_rad: float = 0.0
    max_step_excess_rad: float = 0.0
    per_joint: dict[str, int] = field(default_factory=dict)


CLOCK_BUDGET_PERIODS = 3.0
"""How much of each joint's velocity limit the clock budget saves up: three control periods'
worth. The control loop sends no tick before it is due, follows a tick that ended less than a
period behind the next one's time at once, and skips ticks when further behind: every such
sequence keeps its full steps (tests/pipeline/test_loop_under_load.py); commands sent faster
than real time get only the time that passed. Two periods' worth held a loop's steps back
whenever a sleep overshot by more than a period."""


class SafetyLayer(JointBackend):
    """Wraps ``backend`` (any JointBackend for ``config``) and clamps every command.

    ``clock`` (seconds): what the step bound holds against besides the commands' stamps (see
    the module docstring); the wall clock by default, the loop's own clock where it runs on
    simulated time, None where no robot moves in real time (a recording of a conversion, a
    benchmark of the pipeline's arithmetic). The backend is told it too, for its own check."""

    def __init__(
        self,
        config: RobotConfig | str | os.PathLike[str],
        backend: JointBackend,
        *,
        clock: Callable[[], float] | None = time.monotonic,
    ) -> None:
        config = as_robot_config(config)
        self.config = config
        self.backend = backend
        self.lower = config.lower
        self.upper = config.upper
        self.max_velocity = config.max_velocity
        self.period_s = 1.0 / config.control_rate_hz
        self._names = config.joint_names  # a property that rebuilds its tuple on every read
        self.stats = ClipStats(per_joint=dict.fromkeys(config.joint_names, 0))
        self._prev_q: FloatArray | None = None
        self._prev_t: float | None = None
        # A backend that rounds commands to ticks: what it last wrote, and its tick size.
        backend.set_command_period(self.period_s)  # its own step check, at this period
        self._budget: VelocityBudget | None = None
        if clock is not None:
            backend.set_command_clock(clock)
            depth_s = CLOCK_BUDGET_PERIODS * self.period_s
            self._budget = VelocityBudget(self.max_velocity, depth_s, clock)
        self._quantum = backend.position_quantum_rad
        self._prev_sent: FloatArray | None = None
        # send() clamps against the last command sent and sends, as one step: two threads
        # sending at once would each clamp against the same last command (1.4-5x the limit).
        # Re-entrant: a backend may send through the layer from its own send. A caller that
        # clamps and sends in two calls (the control loop) holds it around both.
        self.send_lock = threading.RLock()
        if self._quantum is not None:
            _check_ticks_per_period(config, self._quantum, self.period_s)

    @property
    def connected(self) -> bool:
        return self.backend.connected

    @property
    def position_quantum_rad(self) -> FloatArray | None:
        return self.backend.position_quantum_rad

    def rounded(self, q: FloatArray) -> FloatArray:
        return self.backend.rounded(q)

    def connect(self) -> None:
        self.backend.connect()
        state = self.backend.read_state()
        self.reset(state.q)

    def reset(self, q: FloatArray | None) -> None:
        """Start the step bound from ``q``. None: from where the backend reports the robot when
        the next command comes (read then, if it is connected; a backend that is not takes the
        next command clamped to the limits only, as the start of a recording)."""
        self._prev_q = None if q is None else np.clip(q, self.lower, self.upper)
        self._prev_t = None
        if self._budget is not None:
            self._budget.fill()
        # Where the servos are, on their grid: the first command's ticks keep to the bound
        # from there too (the nearest tick could step half a tick past a ramp's step).
        self._prev_sent = (
            None if self._prev_q is None or self._quantum is None else self.rounded(self._prev_q)
        )

    def disconnect(self) -> None:
        self.backend.disconnect()

    def read_state(self) -> JointState:
        return self.backend.read_state()

    def clamp(self, cmd: JointCommand, max_step: FloatArray | None = None) -> JointCommand:
        """The safe version of ``cmd`` (updates the statistics; sends nothing). ``max_step``
        (J,) rad: a tighter bound on this command's step from the last one sent, as the
        caller moved it (a ramp at a fraction of the speed): a backend's tick rounding keeps to
        it too (the nearest tick could step past it by half a tick)."""
        q = cmd.q
        names = self._names
        if q.shape != (len(names),):
            raise UnsafeCommandError(
                f"command has shape {q.shape}, robot {self.config.name} has {len(names)} joints; "
                "nothing was sent"
            )
        finite = np.isfinite(q)
        if not finite.all():
            bad = ~finite
            joints = tuple(n for n, b in zip(names, bad, strict=True) if b)
            raise UnsafeCommandError(
                f"command has NaN/inf for joints {', '.join(joints)}; nothing was sent. Check "
                "the retargeting stage's output",
                joints=joints,
            )
        # Beyond a turn is other units (degrees): refused rather than clamped, which had driven
        # every joint to a limit at full speed.
        bad = beyond_a_turn(q)
        if bad.any():
            joints = tuple(n for n, b in zip(names, bad, strict=True) if b)
            raise UnsafeCommandError(
                f"command has {', '.join(joints)} beyond a turn ({float(q[bad][0]):g} rad): no "
                "servo of a humanoid goes there, so the numbers are not radians (degrees? pass "
                "np.radians of them); nothing was sent",
                joints=joints,
            )
        # minimum(maximum(·)) is np.clip (inputs are finite here) without its wrapper's cost.
        lower, upper = self.lower, self.upper
        if self._prev_q is None and self.backend.connected:
            # Wrapped round a robot already connected, or reset(None): the first step is bounded
            # from where the servos are, not only clamped to the limits.
            self.reset(self.backend.read_state().q)
        prev = self._prev_q
        bound: FloatArray | None = None
        stamp_bound: FloatArray | None = None
        if prev is None:
            q_safe = np.minimum(np.maximum(q, lower), upper)
        else:
            dt = self.period_s
            if self._prev_t is not None:
                if not cmd.t_s > self._prev_t:  # NaN included
                    raise UnsafeCommandError(
                        f"command time {cmd.t_s!r} s does not come after the previous command's "
                        f"{self._prev_t!r} s: the step bound needs the time between commands; "
                        "nothing was sent (stamp each JointCommand with an increasing t_s)"
                    )
                # A period to float rounding is a period: stamps k / rate lose a few ulps, and
                # a trajectory whose steps are exactly v_max / rate must not count as clipped.
                gap = cmd.t_s - self._prev_t
                dt = self.period_s if gap >= self.period_s * (1.0 - 1e-9) else gap
            bound = stamp_bound = self.max_velocity * dt
            if self._budget is not None:
                bound = np.minimum(bound, self._budget.available())
            # prev lies inside the limits, so the limits and the step box intersect, and one
            # clamp to the intersection is the limit clamp followed by the step clamp.
            lo = np.maximum(prev - bound, lower)
            hi = np.minimum(prev + bound, upper)
            q_safe = np.minimum(np.maximum(q, lo), hi)
        s = self.stats
        s.commands += 1
        if not (q_safe == q).all():  # the bookkeeping only for a command that was changed
            q_pos = np.minimum(np.maximum(q, lower), upper)
            pos_clipped = q_pos != q
            moved = q_safe != q_pos
            if stamp_bound is not None and self._budget is not None and prev is not None:
                # What the stamps alone allowed; the clock held a joint back where it differs.
                q_stamp = np.minimum(
                    np.maximum(q_pos, np.maximum(prev - stamp_bound, lower)),
                    np.minimum(prev + stamp_bound, upper),
                )
                step_clipped = q_stamp != q_pos
                by_clock = q_safe != q_stamp
            else:
                step_clipped, by_clock = moved, np.zeros_like(moved)
            s.commands_clipped += 1
            s.position_clips += int(pos_clipped.sum())
            s.step_clips += int(step_clipped.sum())
            s.clock_clips += int(by_clock.sum())
            s.max_position_excess_rad = max(
                s.max_position_excess_rad, float(np.max(np.abs(q - q_pos)))
            )
            s.max_step_excess_rad = max(
                s.max_step_excess_rad, float(np.max(np.abs(q_pos - q_safe)))
            )
            for n, c in zip(names, pos_clipped | moved, strict=True):
                if c:
                    s.per_joint[n] += 1
        if bound is not None and max_step is not None:
            bound = np.minimum(bound, max_step)
        last_sent = self._prev_sent
        sent = self._on_the_grid(q_safe, bound)
        if prev is not None and self._budget is not None:
            travel = np.abs(q_safe - prev)
            if last_sent is not None and self._quantum is not None:
                # The servos move by whole ticks: a joint dithering across a tick's edge
                # travels a tick a command there, which the backend's own budget counts.
                travel = np.maximum(travel, np.abs(sent - last_sent))
            self._budget.spend(travel)
        self._prev_q = q_safe
        self._prev_t = cmd.t_s
        return JointCommand(sent, cmd.t_s)

    def _on_the_grid(self, q_safe: FloatArray, bound: FloatArray | None) -> FloatArray:
        """What a backend that rounds to ticks will write, kept within ``bound`` of what it
        wrote last: where the nearest tick would step past ``v_max · dt``, the farthest tick
        within it instead. The bound above runs on the unrounded commands, so the robot's
        effective top speed is whole ticks per period, and nothing accumulates upstream."""
        quantum = self._quantum
        if quantum is None:
            return q_safe
        sent = self.backend.rounded(q_safe)
        last = self._prev_sent
        if bound is not None and last is not None:
            step = sent - last
            over = np.abs(step) > bound + 1e-12
            if over.any():
                whole = np.floor(bound / quantum + 1e-9) * quantum
                sent = np.where(over, last + np.sign(step) * whole, sent)
                # The same ticks; rounded again so the floats are exactly what gets written.
                sent = self.backend.rounded(sent)
        self._prev_sent = sent
        return sent

    def send(self, cmd: JointCommand) -> JointCommand:
        """Clamp ``cmd`` and send it; callers on several threads are taken one at a time."""
        with self.send_lock:
            return self.backend.send(self.clamp(cmd))

    def report(self) -> str:
        """One line per fact, for the CLI / logs."""
        s = self.stats
        worst = sorted(((c, n) for n, c in s.per_joint.items() if c), reverse=True)[:5]
        lines = [
            f"safety: {s.commands_clipped} of {s.commands} commands clipped "
            f"({s.position_clips} joint limit clips, max excess {s.max_position_excess_rad:.4f} "
            f"rad; {s.step_clips} velocity clips, max excess {s.max_step_excess_rad:.4f} rad)"
        ]
        if s.clock_clips:
            lines.append(
                f"{s.clock_clips} joint steps held to the time that really passed: commands came "
                "faster than real time (a late loop catching up, or a caller that does not wait "
                "for its stamps)"
            )
        if worst:
            lines.append("most clipped: " + ", ".join(f"{n} ({c})" for c, n in worst))
        return "\n".join(lines)


MIN_TICKS_PER_PERIOD = 2.0
"""A joint must be able to move this many ticks per control period at its velocity limit: with
fewer, whole ticks within ``v_max · dt`` leave it nearly still (a quarter-period tick of
``--wake-on-input`` gets a quarter of them)."""


def check_servo_rate(config: RobotConfig, rate_hz: float) -> None:
    """Raise :class:`UnsafeCommandError` if ``config``'s servos, whose goals are whole ticks,
    cannot run at ``rate_hz`` (as the Dynamixel backend would on connecting): a simulated
    robot refuses the rate its real servos would."""
    from robot_retarget.robot.servo_units import ServoUnits

    _check_ticks_per_period(config, ServoUnits(config).rad_per_tick, 1.0 / rate_hz)


def _check_ticks_per_period(config: RobotConfig, quantum: FloatArray, period_s: float) -> None:
    ticks = config.max_velocity * period_s / np.asarray(quantum)
    slow = ticks < MIN_TICKS_PER_PERIOD
    if not slow.any():
        return
    j = int(np.argmin(ticks))
    joint = config.joints[j]
    top_hz = float(config.max_velocity[j] / (MIN_TICKS_PER_PERIOD * quantum[j]))
    raise UnsafeCommandError(
        f"at {1.0 / period_s:g} Hz joint {joint.name} moves {ticks[j]:.2f} servo ticks per "
        f"period at its velocity limit; commands rounded to ticks need at least "
        f"{MIN_TICKS_PER_PERIOD:g}: run at {top_hz:.0f} Hz or less",
        joints=(joint.name,),
    )
