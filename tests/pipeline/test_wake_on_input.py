"""LoopSettings.wake_on_input: a frame that arrives between ticks is retargeted at once, and
every command still keeps to v_max over the interval it actually had (on a fake clock)."""

from __future__ import annotations

import numpy as np

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.pipeline.loop import ControlLoop, LoopResult, LoopSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend
from tests.pipeline.scripted import FakeClock, ScriptedSource


class WaitableSource(ScriptedSource):
    """A ScriptedSource the loop can wait on: the fake clock jumps to the next arrival."""

    def __init__(self, motion: HumanMotion, clock: FakeClock) -> None:
        super().__init__(motion)
        self.clock = clock

    def wait_for_frame(self, timeout_s: float) -> bool | None:
        if self._t0 is None or self._next >= self.motion.num_frames:
            self.clock.sleep(timeout_s)
            return False
        arrival = self._t0 + self._next / self.motion.fps
        if arrival > self.clock.t + timeout_s:
            self.clock.sleep(timeout_s)
            return False
        self.clock.t = max(self.clock.t, arrival)
        return True


def _run(step: RetargetStep, op3: RobotConfig, wake: bool) -> tuple[LoopResult, ControlLoop]:
    clock = FakeClock()
    clip = demo_motion(fps=30.0).frames(0, 90)  # 3 s at 30 fps: arrivals between the ticks
    step.reset(op3.init_pose)
    settings = LoopSettings(rate_hz=125.0, ramp_speed_fraction=1.0, wake_on_input=wake)
    loop = ControlLoop(step, WaitableSource(clip, clock), SimBackend(op3, clock=clock.now),
                       settings, record=True, clock=clock.now, sleep=clock.sleep)  # fmt: skip
    return loop.run(), loop


def test_woken_ticks_keep_the_velocity_limit_over_their_own_interval(
    step: RetargetStep, op3: RobotConfig
) -> None:
    result, loop = _run(step, op3, wake=True)
    assert loop.early_ticks > 0
    t = np.array([e.t_s for e in result.log])
    q = np.array([e.q for e in result.log])
    dt = np.diff(t)
    assert dt.min() < loop.period_s * 0.99  # some ticks really were early
    assert dt.min() >= 0.25 * loop.period_s - 1e-12  # never closer than a quarter period
    step_rad = np.abs(np.diff(q, axis=0))
    allowed = op3.max_velocity[None, :] * np.minimum(dt, loop.period_s)[:, None]
    assert np.all(step_rad <= allowed * (1 + 1e-6) + 1e-12)
    assert np.all(q >= op3.lower - 1e-12)
    assert np.all(q <= op3.upper + 1e-12)


def test_waking_on_input_shortens_the_wait_for_the_tick(
    step: RetargetStep, op3: RobotConfig
) -> None:
    _, ticked = _run(step, op3, wake=False)
    _, woken = _run(step, op3, wake=True)
    assert ticked.early_ticks == 0
    wait_ticked = np.median(np.array(ticked.budget.samples["wait for tick"]))
    wait_woken = np.median(np.array(woken.budget.samples["wait for tick"]))
    assert wait_ticked > 0.0
    assert wait_woken < 0.5 * wait_ticked
