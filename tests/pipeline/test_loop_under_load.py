"""The control loop on a loaded machine: its sleeps overshoot and it falls behind its schedule.
A loop at its rate, however late its ticks, is never held back by the safety layer's clock
budget: that budget is for callers that send faster than real time, and the loop never does."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest

from robot_retarget.hardware.safety import SafetyLayer
from robot_retarget.hardware.types import JointCommand
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.nn.inference import LoadedModel
from robot_retarget.optimize import Retargeter
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings, Mode
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend
from tests.pipeline.scripted import FakeClock, ScriptedSource


class OversleepingClock(FakeClock):
    """A sleep that, one time in three, overshoots by up to ``most`` seconds (a busy machine)."""

    def __init__(self, most_s: float, seed: int) -> None:
        super().__init__()
        self.most_s = most_s
        self.rng = np.random.default_rng(seed)
        self.overshoots = 0

    def sleep(self, dt_s: float) -> None:
        super().sleep(dt_s)
        if self.rng.random() < 1 / 3:
            self.t += self.rng.uniform(0.0, self.most_s)
            self.overshoots += 1


@pytest.mark.parametrize("most_periods", [1.5, 2.5, 6.0])
def test_late_ticks_keep_their_full_steps(
    op3: RobotConfig,
    copy_model: LoadedModel,
    retargeter: Retargeter,
    demo: HumanMotion,
    most_periods: float,
) -> None:
    """The demo played four times as fast, so joints run at their velocity limit, the start and
    the smooth stop at full speed too; sleeps overshoot by up to ``most_periods`` (a tick late
    by more than one period is followed by the next at once, two behind skips one). Before,
    with two periods of budget and a smooth stop that sent missed ticks back to back, 448-596
    joint steps were held back here."""
    fast = dataclasses.replace(demo, fps=4 * demo.fps)
    step = RetargetStep(op3, copy_model, fast.skeleton, retargeter=retargeter)
    period = 1.0 / op3.control_rate_hz
    clock = OversleepingClock(most_periods * period, seed=3)
    backend = SimBackend(op3, clock=clock.now)
    loop = ControlLoop(step, ScriptedSource(fast), backend, LoopSettings(ramp_speed_fraction=1.0),
                       record=True, clock=clock.now, sleep=clock.sleep)  # fmt: skip
    result = loop.run()
    assert clock.overshoots > 20
    q = np.array([e.q for e in result.log])
    # Joints did move at their limit (else no budget could be short) ...
    full = np.abs(np.diff(q, axis=0)) >= 0.999 * op3.max_velocity * period
    assert full.sum() > 50
    # ... and the clock never held one back.
    assert result.safety.clock_clips == 0, result.safety
    assert result.safety.commands_clipped == 0


class LateThenInterrupted(FakeClock):
    """Sleeps keep time until call ``late_at``, which overshoots by ``overshoot_s``; the sleep
    after it is cut short by Ctrl-C (the loop's smooth stop then runs)."""

    def __init__(self, late_at: int, overshoot_s: float) -> None:
        super().__init__()
        self.calls = 0
        self.late_at = late_at
        self.overshoot_s = overshoot_s

    def sleep(self, dt_s: float) -> None:
        self.calls += 1
        if self.calls == self.late_at + 1:
            raise KeyboardInterrupt
        super().sleep(dt_s)
        if self.calls == self.late_at:
            self.t += self.overshoot_s


def test_a_stop_right_after_a_late_tick_keeps_to_the_schedule(
    op3: RobotConfig, copy_model: LoadedModel, retargeter: Retargeter, demo: HumanMotion
) -> None:
    """Ctrl-C in the sleep after a tick 1.9 periods late and the one sent at once after it: the
    smooth stop's first step waits for the stream's next tick (it went out at once, and
    joints at full speed were held back: 247 joint steps)."""
    fast = dataclasses.replace(demo, fps=4 * demo.fps)
    step = RetargetStep(op3, copy_model, fast.skeleton, retargeter=retargeter)
    period = 1.0 / op3.control_rate_hz
    clock = LateThenInterrupted(late_at=60, overshoot_s=1.9 * period)
    backend = SimBackend(op3, clock=clock.now)
    loop = ControlLoop(step, ScriptedSource(fast), backend, LoopSettings(ramp_speed_fraction=1.0),
                       record=True, clock=clock.now, sleep=clock.sleep)  # fmt: skip
    result = loop.run()
    assert result.interrupted
    assert result.safety.clock_clips == 0, result.safety


def _slow_when_stopping(
    loop: ControlLoop, clock: FakeClock, overshoot_s: float
) -> Callable[[float], None]:
    """A sleep that overshoots by ``overshoot_s`` once the loop is on its smooth stop."""

    def sleep(dt_s: float) -> None:
        clock.sleep(dt_s + (overshoot_s if loop.mode is Mode.STOPPING else 0.0))

    return sleep


def test_the_smooth_stop_keeps_its_speed_when_ticks_are_missed(
    op3: RobotConfig, copy_model: LoadedModel, retargeter: Retargeter, demo: HumanMotion
) -> None:
    """Every sleep of the stop overshoots by three periods: the loop skips those ticks, and each
    step it does send covers their time too, so the stop takes about as long as on an idle
    machine (one step a tick sent had made it four times as slow, past its deadline)."""
    period = 1.0 / op3.control_rate_hz
    durations = []
    for overshoot in (0.0, 3.0 * period):
        step = RetargetStep(op3, copy_model, demo.skeleton, retargeter=retargeter)
        clock = FakeClock()
        backend = SimBackend(op3, clock=clock.now)
        loop = ControlLoop(step, ScriptedSource(demo), backend, LoopSettings(duration_s=1.5),
                           record=True, clock=clock.now, sleep=clock.sleep)  # fmt: skip
        loop.sleep = _slow_when_stopping(loop, clock, overshoot)
        result = loop.run()
        stops = [e for e in result.log if e.mode is Mode.STOPPING]
        np.testing.assert_allclose(stops[-1].q, op3.safe_pose, atol=1e-9)  # reached
        durations.append(stops[-1].t_s - stops[0].t_s)
        assert result.safety.clock_clips == 0
    assert durations[0] > 0.3  # a real move (the demo's pose is not the safe pose)
    assert durations[1] < durations[0] + 5 * period


def test_the_loop_sends_under_the_safety_layers_lock_and_leaves_the_steps_tell_as_it_was(
    op3: RobotConfig, copy_model: LoadedModel, retargeter: Retargeter, demo: HumanMotion
) -> None:
    """Another thread sending on the same layer waits while the loop clamps and sends (the
    lock SafetyLayer.send takes); frames that look x-y-z-w are the source's to tell, so the
    step does not warn inside the loop, and warns again after it."""
    import threading
    import warnings

    from robot_retarget.pipeline.step import ConventionWarning

    held: list[bool] = []

    class Probe(SimBackend):
        def send(self, cmd: JointCommand) -> JointCommand:
            other = threading.Thread(target=lambda: held.append(not lock.acquire(blocking=False)))
            other.start()
            other.join()
            return super().send(cmd)

    rolled = dataclasses.replace(demo, local_quats=np.roll(demo.local_quats, -1, axis=-1))
    step = RetargetStep(op3, copy_model, rolled.skeleton, retargeter=retargeter)
    clock = FakeClock()
    safety = SafetyLayer(op3, Probe(op3, clock=clock.now), clock=clock.now)
    lock = safety.send_lock
    loop = ControlLoop(step, ScriptedSource(rolled), safety, LoopSettings(duration_s=1.5),
                       clock=clock.now, sleep=clock.sleep)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConventionWarning)
        loop.run()
    assert held
    assert all(held)
    assert step.warn_conventions
    step.reset()  # outside the loop the same frames are told
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for k in range(rolled.num_frames):
            step(rolled.local_quats[k], rolled.root_pos[k], 1 / rolled.fps)
    assert any(issubclass(w.category, ConventionWarning) for w in caught)
