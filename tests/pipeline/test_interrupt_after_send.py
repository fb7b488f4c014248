"""A Ctrl-C that lands after a tick's command went out but before the loop's tick counter moves
on: the smooth stop still reaches the safe pose (its first stamp must come after that command's,
or the safety layer refuses it)."""

from __future__ import annotations

import dataclasses

import numpy as np

from robot_retarget.hardware.safety import SafetyLayer
from robot_retarget.hardware.types import JointCommand
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn.inference import load_model
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sim.robot_bus import SimulatedRobotBus
from robot_retarget.sources.replay import ReplaySource
from tests.pipeline.scripted import FakeClock


def test_ctrl_c_during_the_stats_line_still_stops_smoothly() -> None:
    op3 = load_robot_config("op3")
    clip = demo_motion(fps=30.0).frames(0, 61)
    step = RetargetStep(op3, load_model("copy"), clip.skeleton)
    step.reset()
    clock = FakeClock()
    fired: list[str] = []

    def report(line: str) -> None:
        if "ticks" in line and not fired:  # the periodic stats line, after a command went out
            fired.append(line)
            raise KeyboardInterrupt

    settings = LoopSettings(ramp_speed_fraction=1.0, report_every_s=0.3)
    backend = SimBackend(op3, clock=clock.now)
    loop = ControlLoop(
        step, ReplaySource(clip), backend, settings, report=report, clock=clock.now,
        sleep=clock.sleep,
    )  # fmt: skip
    result = loop.run()
    assert fired
    assert result.interrupted
    np.testing.assert_allclose(loop._q_cmd, op3.safe_pose, atol=1e-6)  # the last command


def test_a_backend_behind_a_slower_loop_takes_that_loop_s_steps() -> None:
    """stream --rate 50 on OP3 (config 125 Hz): the safety layer bounds steps by the loop's
    period, and the Dynamixel backend's own step check must use that period, not the config's."""
    op3 = load_robot_config("op3")
    loop_config = dataclasses.replace(op3, control_rate_hz=50.0)
    with SimulatedRobotBus(op3, op3.init_pose) as sim:
        safety = SafetyLayer(loop_config, sim.backend())
        safety.connect()
        try:
            target = op3.init_pose.copy()
            target[op3.joint_index("head_pan")] = 0.8
            for k in range(1, 20):
                safety.send(JointCommand(target, k * 0.02 * (1 + 1e-9)))
        finally:
            safety.disconnect()
