"""The fixed-rate control loop: source → interpolation (→ an opt-in One-Euro input filter) →
RetargetStep → safety → backend.

One thread (the caller's) owns the backend; sources receive on their own threads. Each tick
(default: the robot config's ``control_rate_hz``) drains the source, samples the interpolated
human pose and sends one command. Modes:

- WAITING: no input yet; nothing is sent (the robot stays as it is, torque untouched).
- RAMP_IN (start-up, after the safe pose, and after a hold that interrupted a ramp): the
  optimizer tracks the motion on its own, from the first frame solved to its optimum; the
  robot pursues that trajectory from its present pose at ``ramp_speed_fraction`` of each
  joint's max velocity for at least ``ramp_min_s``, then catches up and joins it
  (:mod:`robot_retarget.pipeline.start_ramp`).
- TRACKING: the retargeted command, every tick.
- HOLD: input silent for more than ``hold_after_s`` (200 ms): the last command is held.
- SAFE: silent for more than ``safe_after_s`` (2 s): move to the config's safe pose at the ramp
  speed; there, the torque goes off when the config says ``torque_off_at_safe_pose``.

Ctrl-C (KeyboardInterrupt), the end of ``duration_s`` or the end of a finite source stops
smoothly: the robot moves to the safe pose at the ramp speed (at most ``stop_timeout_s``), then
the backend disconnects, which switches the torque off. A second Ctrl-C skips the move.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.hardware.safety import ClipStats, SafetyLayer
from robot_retarget.hardware.types import JointCommand
from robot_retarget.pipeline.input_filter import OneEuroFilter, OneEuroSettings
from robot_retarget.pipeline.interpolation import FrameInterpolator
from robot_retarget.pipeline.latency_budget import LatencyBudget
from robot_retarget.pipeline.live_mailbox import LiveFrame, Mailbox
from robot_retarget.pipeline.live_stats import LiveStats, StatsSnapshot
from robot_retarget.pipeline.start_ramp import RampOutcome, RampSettings, StartRamp, toward
from robot_retarget.pipeline.step import RetargetStep, StepStats
from robot_retarget.sources.base import MotionSource

_MIN_EARLY_TICK_PERIODS = 0.25


class Mode(str, enum.Enum):
    WAITING = "waiting"
    RAMP_IN = "ramp-in"
    TRACKING = "tracking"
    HOLD = "hold"
    SAFE = "safe"
    STOPPING = "stopping"


@runtime_checkable
class TorqueSwitch(Protocol):
    """A backend that can release the servos without disconnecting (Dynamixel)."""

    def torque_off(self) -> None: ...


@dataclass(frozen=True)
class LoopSettings:
    rate_hz: float | None = None  # None: the robot config's control_rate_hz
    hold_after_s: float = 0.2
    safe_after_s: float = 2.0
    ramp_speed_fraction: float = 0.25
    stop_timeout_s: float = 3.0
    ramp_min_s: float = 0.5  # the ramp speed holds at least this long after every (re)start
    catch_up_rad: float = 0.2  # then the pursuit speeds up once every joint is this close
    ramp_rise_s: float = 0.5  # from the ramp speed to the velocity limit
    ramp_timeout_s: float = 3.0
    report_every_s: float = 5.0
    duration_s: float | None = None
    delay_periods: float = 1.0  # playout delay, in (measured) input frame periods
    # While tracking, a frame that arrives between ticks is retargeted at once (a tick of the
    # shorter interval since the last one, bounded to v_max · that interval) and the schedule
    # restarts from there, instead of waiting up to a period. Sources that cannot be waited
    # on (replay) tick as usual.
    wake_on_input: bool = False
    # An opt-in One-Euro filter on the interpolated input (robot_retarget.pipeline.input_filter):
    # less servo chatter from a jittery pose estimator, at the price of some lag.
    input_filter: OneEuroSettings | None = None

    def __post_init__(self) -> None:
        if self.rate_hz is not None and not self.rate_hz > 0:
            raise ValueError(f"rate_hz must be positive, got {self.rate_hz}")
        if not 0.0 < self.hold_after_s < self.safe_after_s:
            raise ValueError("need 0 < hold_after_s < safe_after_s")
        self.ramp  # noqa: B018  (validates the ramp's settings)

    @property
    def ramp(self) -> RampSettings:
        return RampSettings(
            fraction=self.ramp_speed_fraction,
            min_s=self.ramp_min_s,
            catch_up_rad=self.catch_up_rad,
            rise_s=self.ramp_rise_s,
            timeout_s=self.ramp_timeout_s,
        )


@dataclass(frozen=True)
class LogEntry:
    """One tick: loop time, the sender-time it played, the mode, the command (rad) handed to
    the backend after the safety layer (before any rounding to servo ticks) and its stamp."""

    t_s: float
    play_t_s: float
    mode: Mode
    q: FloatArray
    # The command's stamp: the safety layer's timeline, on which every step keeps within the
    # velocity limit (loop time jitters around it; a recording is written on it).
    stamp_s: float = math.nan


@dataclass
class LoopResult:
    stats: StatsSnapshot
    safety: ClipStats
    step: StepStats
    interrupted: bool
    transitions: list[tuple[float, Mode]] = field(default_factory=list)
    log: list[LogEntry] = field(default_factory=list)
    torque_released: bool = False
    # The robot's pose as read when streaming began (servo ticks on a bus): the first
    # command's step is bounded from here.
    start_q: FloatArray | None = None
    # A second Ctrl-C during the smooth stop: the move to the safe pose was cut short.
    stop_skipped: bool = False


class ControlLoop:
    """Runs a source through a RetargetStep into a backend (always behind a SafetyLayer)."""

    def __init__(
        self,
        step: RetargetStep,
        source: MotionSource,
        backend: JointBackend,
        settings: LoopSettings | None = None,
        *,
        report: Callable[[str], None] | None = None,
        record: bool = False,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        mailbox: Mailbox[LiveFrame] | None = None,
    ) -> None:
        self.step = step
        self.config = step.config
        self.source = source
        self.settings = settings or LoopSettings()
        rate = self.settings.rate_hz or self.config.control_rate_hz
        self.period_s = 1.0 / rate
        # The loop's period is the safety layer's control period (its step bound).
        loop_config = dataclasses.replace(self.config, control_rate_hz=rate)
        # The safety layer keeps time on the loop's clock: simulated time where the loop runs
        # on it, so its clock budget bounds steps by the time that passed there.
        self.safety = (
            backend
            if isinstance(backend, SafetyLayer)
            else SafetyLayer(loop_config, backend, clock=clock)
        )
        self.report = report or (lambda _line: None)
        self.record = record
        self.clock = clock
        self.sleep = sleep
        self.stats = LiveStats()
        self.mode = Mode.WAITING
        self.transitions: list[tuple[float, Mode]] = []
        self.log: list[LogEntry] = []
        self._ramp = StartRamp(self.settings.ramp, self.config.max_velocity * self.period_s)
        self._ramp_step = self._ramp.slow_step  # also the speed to the safe pose and at stop
        self._q_cmd: FloatArray = np.array(self.config.init_pose, dtype=np.float64)
        self._released = False
        self._ever_released = False
        self._sent_any = False
        self._last_seq: int | None = None
        self._start_q: FloatArray | None = None
        self._settle_next = False  # the next step solves its frame to its optimum
        f = self.settings.input_filter
        self._input_filter = None if f is None else OneEuroFilter(f)
        self._ramp_done = False
        # A pose is reached when every command is within a hair of it, or within a tick where
        # the backend writes ticks (its commands are on the tick grid, the pose need not be).
        quantum = self.safety.position_quantum_rad
        self._reach_tol = 1e-6 + (0.0 if quantum is None else np.asarray(quantum))
        self._k = 0  # tick counter: command stamps are k periods apart
        self._last_stamp = -math.inf
        # A watcher's (stream --view) one-slot mailbox: one LiveFrame per command, never waited on.
        self.mailbox = mailbox
        self._silence_s = 0.0
        # Per input frame: arrival → tick → sample → step → clamp → sent (stream prints it).
        self.budget = LatencyBudget()
        self._t_tick = self._t_clamped = self._t_sent = 0.0
        # The current tick's interval (the optimizer's and the safety layer's dt): the period,
        # or less for a tick woken by input; the stamps shift back by what such ticks saved.
        self._dt_s = self.period_s
        self._stamp_shift_s = 0.0
        self.early_ticks = 0
        self._next_due = -math.inf  # when the stream's next tick is due

    # ----------------------------------------------------------------------------- helpers
    def _set_mode(self, mode: Mode, now: float, why: str) -> None:
        if mode is not self.mode:
            self.mode = mode
            self.transitions.append((now, mode))
            self.report(f"[{mode.value}] {why}")

    def _send(
        self, q: FloatArray, now: float, play_t: float, max_step: FloatArray | None = None
    ) -> None:
        """``max_step``: the step ``q`` was moved by at most (a ramp's), kept on the tick grid."""
        # Stamps 1 ppb more than a period apart: the safety layer bounds each step by exactly
        # v_max · period, the optimizer's bound (see convert.py).
        stamp = self._k * self.period_s * (1.0 + 1e-9) + self._stamp_shift_s
        # The safety layer refuses a stamp that does not advance: a command right after one
        # sent just before an interrupt (the tick counter not yet moved on, the smooth stop's
        # first) gets a hair more, so it holds still for that tick.
        stamp = max(stamp, self._last_stamp + 1e-9 * self.period_s)
        self._last_stamp = stamp
        # As SafetyLayer.send, in two steps: the loop keeps the safe command itself (on the
        # backend's tick grid where it rounds), not the backend's echo.
        with self.safety.send_lock:  # one sender at a time, as SafetyLayer.send
            safe = self.safety.clamp(JointCommand(q, stamp), max_step)
            self._t_clamped = self.clock()
            self.safety.backend.send(safe)
            self._t_sent = self.clock()
        self._q_cmd = np.array(safe.q, dtype=np.float64)
        self._sent_any = True
        self.stats.commands += 1
        if self.record:
            self.log.append(LogEntry(now, play_t, self.mode, self._q_cmd, stamp))
        if self.mailbox is not None:
            stats = self.stats
            self.mailbox.put(
                LiveFrame(
                    now,
                    self.mode.value,
                    q,
                    self._q_cmd,
                    self._silence_s,
                    stats.latency_s[-1] if stats.latency_s else float("nan"),
                    stats.jitter_s[-1] if stats.jitter_s else 0.0,
                    self.safety.stats.commands_clipped,
                )
            )

    def _present(self) -> FloatArray:
        return np.array(self.safety.read_state().q, dtype=np.float64)

    def _release(self) -> None:
        inner = self.safety.backend
        if isinstance(inner, TorqueSwitch):
            inner.torque_off()
            self._released = True
            self._ever_released = True
            self.report("[safe] at the safe pose: torque off (torque_off_at_safe_pose)")

    # ----------------------------------------------------------------------------- run
    def run(self) -> LoopResult:
        """Connect, stream until stopped, stop smoothly, disconnect (torque off).

        Any error stops the loop too: the backend still disconnects (torque off) and the
        source still stops before the error propagates.
        """
        interrupted = stop_skipped = False
        # Each source tells its own sender's conventions: the step's tell is off while it
        # streams here (and as it was again after).
        warn_conventions, self.step.warn_conventions = self.step.warn_conventions, False
        self.safety.connect()
        try:
            try:
                self._stream()
            except KeyboardInterrupt:
                interrupted = True
                self.report("interrupted: stopping smoothly (Ctrl-C again to switch off at once)")
            try:
                self._smooth_stop()
            except KeyboardInterrupt:
                interrupted = stop_skipped = True
        finally:
            self.step.warn_conventions = warn_conventions
            try:
                self.safety.disconnect()
            finally:
                self.source.stop()
        # Not reported here: the caller prints the final line with its summary (it was twice).
        snapshot = self.stats.snapshot(self.source.stats)
        return LoopResult(
            stats=snapshot,
            safety=self.safety.stats,
            step=self.step.stats,
            interrupted=interrupted,
            stop_skipped=stop_skipped,
            transitions=list(self.transitions),
            log=self.log,
            torque_released=self._ever_released,
            start_q=self._start_q,
        )

    def _stream(self) -> None:
        s = self.settings
        self._q_cmd = self._present()
        self._start_q = self._q_cmd.copy()
        described = self.source.describe()
        self.source.start()
        if self.source.describe() != described:  # e.g. port 0: the port the system chose
            self.report(f"listening on {self.source.describe()}")
        # Known once started (a tcp-bvh stream sends its skeleton in the header).
        self.step.set_source(self.source.skeleton)
        self.step.warm_up()
        interp = FrameInterpolator(
            s.delay_periods / self.source.nominal_fps, adapt_periods=s.delay_periods
        )
        start = self.clock()
        next_tick = start
        last_report = start
        last_recv = start
        early = False
        while True:
            now = self.clock()
            if early:  # woken by input: this tick's interval is shorter than the period
                self._dt_s = min(self.period_s, max(now - self._t_tick, 1e-6))
                self._stamp_shift_s -= self.period_s - self._dt_s
                self.early_ticks += 1
            else:
                self._dt_s = self.period_s
            early = False
            self._t_tick = now
            self.stats.ticks += 1
            self.stats.jitter_s.append(max(0.0, now - next_tick))
            for frame in self.source.poll(now):
                interp.push(frame, now)
                last_recv = max(last_recv, frame.recv_s)
            self.stats.late_frames = interp.late_frames
            if s.duration_s is not None and now - start >= s.duration_s:
                return
            newest = interp.newest
            if self.source.finished and (newest is None or interp.play_time(now) > newest.t_s):
                return
            self._silence_s = now - last_recv
            self._tick(now, interp, self._silence_s)
            if now - last_report >= s.report_every_s:
                last_report = now
                self.report(self.stats.snapshot(self.source.stats).line())
            next_tick, missed = self._next_tick(next_tick)
            self._next_due = next_tick  # where a smooth stop takes the schedule over
            self.stats.overruns += missed
            wait = next_tick - self.clock()
            if wait > 0:
                woke = None
                if s.wake_on_input and self.mode is Mode.TRACKING:
                    woke = self.source.wait_for_frame(wait)
                if woke is None:
                    self.sleep(wait)
                elif woke:
                    # Not closer than a quarter period to the last tick: a tiny interval
                    # would allow only a tiny step.
                    gap = self._t_tick + _MIN_EARLY_TICK_PERIODS * self.period_s - self.clock()
                    if gap > 0:
                        self.sleep(gap)
                    early = True
                    next_tick = self.clock()  # the schedule restarts at this tick

    def _next_tick(self, next_tick: float) -> tuple[float, int]:
        """When the tick after the one due at ``next_tick`` is due, and how many ticks were
        skipped to get there. No tick is sent before it is due (but one woken early by input,
        with its shorter step); a tick that ends less than a period behind the next one's time
        is followed by it at once, and a loop further behind skips the ticks it missed rather
        than send them back to back. The safety layer's clock budget (CLOCK_BUDGET_PERIODS
        deep) takes every such sequence in full (tests/pipeline/test_loop_under_load.py)."""
        next_tick += self.period_s
        self._k += 1
        behind = self.clock() - next_tick
        missed = int(behind / self.period_s) if behind > self.period_s else 0
        self._k += missed
        return next_tick + missed * self.period_s, missed

    def _tick(self, now: float, interp: FrameInterpolator, silence_s: float) -> None:
        s = self.settings
        if interp.empty:
            return
        if self.mode is Mode.WAITING:
            self._start_ramp(now, "first input frame: ramping from the present pose")
        elif self.mode in (Mode.TRACKING, Mode.RAMP_IN) and silence_s > s.hold_after_s:
            self._set_mode(Mode.HOLD, now, f"input silent {silence_s:.2f} s: holding the pose")
        elif self.mode is Mode.HOLD and silence_s > s.safe_after_s:
            self._set_mode(Mode.SAFE, now, f"input silent {silence_s:.1f} s: to the safe pose")
        elif self.mode is Mode.HOLD and silence_s <= s.hold_after_s:
            if self._ramp_done:
                # The optimizer goes on from the held command (its velocity box is centred there).
                self.step.retargeter.reset(self._q_cmd)
                self._set_mode(Mode.TRACKING, now, "input back: tracking")
            else:  # the hold interrupted the ramp: start it again
                self._start_ramp(now, "input back: ramping from the held pose")
        elif self.mode is Mode.SAFE and silence_s <= s.hold_after_s:
            if self._released:
                self._q_cmd = self._present()
                self.safety.reset(self._q_cmd)
                self._released = False
            self._start_ramp(now, "input back: ramping from the present pose")

        if self.mode is Mode.HOLD:
            self._send(self._q_cmd, now, interp.play_time(now))
        elif self.mode is Mode.SAFE:
            if self._released:
                return
            q = toward(self._q_cmd, self.config.safe_pose, self._ramp_step)
            self._send(q, now, interp.play_time(now), self._ramp_step)
            reached = bool(np.all(np.abs(self.config.safe_pose - self._q_cmd) < self._reach_tol))
            if reached and self.config.hardware.torque_off_at_safe_pose:
                self._release()
        else:
            self._track(now, interp)

    def _start_ramp(self, now: float, why: str) -> None:
        self.step.reset(self._q_cmd)
        self._settle_next = True
        self._ramp.begin(now)
        self._ramp_done = False
        self._set_mode(Mode.RAMP_IN, now, why)

    def _track(self, now: float, interp: FrameInterpolator) -> None:
        sample = interp.sample(now)
        if sample is None:
            return
        local, root = sample.local_quats, sample.root_pos
        if self._input_filter is not None:
            if self._settle_next:  # a sequence starts: the filter starts over with it
                self._input_filter.reset()
            local, root = self._input_filter(local, root, self._dt_s)
        t_sampled = self.clock()
        out = self.step(local, root, self._dt_s, settle=self._settle_next)
        t_stepped = self.clock()
        self._settle_next = False
        q = out.q
        ramp_step = None
        if self.mode is Mode.RAMP_IN:
            # The optimizer runs ahead on the motion's own trajectory (its velocity box is
            # centred on its own last solution); the robot pursues it.
            q, outcome = self._ramp.advance(now, self._q_cmd, out.q)
            ramp_step = self._ramp.last_step
            if outcome is RampOutcome.ON_TRAJECTORY:
                # q == out.q: the optimizer's history is the robot's, tracking goes on seamlessly.
                self._ramp_done = True
                self._set_mode(Mode.TRACKING, now, "on the motion's trajectory: tracking")
            elif outcome is RampOutcome.TIMED_OUT:
                # Never caught: the optimizer goes on from the robot's pose.
                self.step.retargeter.reset(q)
                self._ramp_done = True
                self._set_mode(Mode.TRACKING, now, "ramp timed out: tracking from here")
        if sample.late:
            self.stats.late_ticks += 1
        self._send(q, now, sample.play_t_s, ramp_step)
        if sample.newest.seq != self._last_seq:
            self._last_seq = sample.newest.seq
            self.stats.latency_s.append(self.clock() - sample.newest.recv_s)
            self.budget.add(
                sample.newest.recv_s,
                self._t_tick,
                t_sampled,
                t_stepped,
                self._t_clamped,
                self._t_sent,
            )

    def _smooth_stop(self) -> None:
        if not self._sent_any or self._released or not self.safety.connected:
            return
        now = self.clock()
        self._set_mode(Mode.STOPPING, now, "moving to the safe pose, then torque off")
        deadline = now + self.settings.stop_timeout_s
        goal = self.config.safe_pose
        # The stream's schedule goes on: its next tick may be almost a period away (a late tick
        # and the one after it just went out), and the first stop step waits for it.
        next_tick = max(now, self._next_due)
        full_step = self.config.max_velocity * self.period_s
        step = self._ramp_step
        while np.any(np.abs(goal - self._q_cmd) >= self._reach_tol) and self.clock() < deadline:
            wait = next_tick - self.clock()
            if wait > 0:
                self.sleep(wait)
            q = toward(self._q_cmd, goal, step)
            self._send(q, self.clock(), float("nan"), step)
            next_tick, missed = self._next_tick(next_tick)
            # Ticks skipped on a busy machine: the next step covers their time too (never more
            # than the velocity limit's period), so the stop keeps its speed and its deadline.
            step = np.minimum(self._ramp_step * (1 + missed), full_step)
