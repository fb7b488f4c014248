"""The control loop on a loaded machine: its sleeps overshoot and it falls behind its schedule.
A loop at its rate, however late its ticks, is never held back by the safety layer's clock
budget: that budget is for callers that send faster than real time, and the loop never does."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.nn.inference import LoadedModel
from robot_retarget.optimize import Retargeter
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
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
