"""LatencyBudget: each input frame's latency split into stages that add up to the total."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.pipeline.latency_budget import STAGES, LatencyBudget
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sources.replay import ReplaySource
from tests.pipeline.scripted import FakeClock

gaps = st.floats(0.0, 0.01, allow_nan=False)


@given(st.floats(-0.005, 0.005), gaps, gaps, gaps, gaps)
def test_stages_add_up_to_the_total(
    arrival_vs_tick: float, poll: float, step: float, clamp: float, send: float
) -> None:
    tick = 10.0
    recv = tick + arrival_vs_tick
    start = max(recv, tick)
    budget = LatencyBudget()
    budget.add(recv, tick, start + poll, start + poll + step, start + poll + step + clamp,
               start + poll + step + clamp + send)  # fmt: skip
    parts = [budget.samples[s][0] for s in STAGES[:-1]]
    assert min(parts) >= 0.0  # a frame that came during the poll waited for nothing
    assert sum(parts) == pytest.approx(budget.samples["total"][0])


def test_the_loop_budgets_every_frame_it_measures(
    step: RetargetStep, demo: HumanMotion, op3: RobotConfig
) -> None:
    clock = FakeClock()
    loop = ControlLoop(step, ReplaySource(demo.frames(0, 31)), SimBackend(op3, clock=clock.now),
                       LoopSettings(ramp_speed_fraction=1.0), clock=clock.now,
                       sleep=clock.sleep)  # fmt: skip
    result = loop.run()
    assert loop.budget.frames == len(loop.stats.latency_s) > 0
    np.testing.assert_allclose(
        np.array(loop.budget.samples["total"]), np.array(loop.stats.latency_s)
    )
    median, _p99 = loop.budget.percentiles_ms("total")
    assert median == pytest.approx(result.stats.latency_median_ms)
    assert "wait for tick" in loop.budget.report()
