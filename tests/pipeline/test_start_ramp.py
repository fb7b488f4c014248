"""The ramped start, on an injected clock: at every stream start and every return from the safe
pose, the first ``ramp_min_s`` of commands move at most ``ramp_speed_fraction`` of each joint's
velocity limit (OP3 at 125 Hz and Poppy at 50 Hz), and the ramp then hands over to tracking."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn.inference import LoadedModel
from robot_retarget.optimize import Retargeter
from robot_retarget.pipeline.loop import ControlLoop, LoopResult, LoopSettings, Mode
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sources.base import MotionSource
from tests.pipeline.scripted import FakeClock, ScriptedSource


@pytest.fixture(scope="module", params=["op3", "poppy_humanoid"])
def robot(request: pytest.FixtureRequest) -> tuple[RobotConfig, Retargeter]:
    config = load_robot_config(request.param)
    return config, Retargeter(config)


@pytest.fixture(scope="module")
def motion() -> HumanMotion:
    return demo_motion(fps=30.0).frames(0, 241)  # 8 s


def _run(
    robot: tuple[RobotConfig, Retargeter],
    copy_model: LoadedModel,
    source: MotionSource,
    settings: LoopSettings,
) -> tuple[ControlLoop, LoopResult]:
    config, retargeter = robot
    step = RetargetStep(config, copy_model, source.skeleton, retargeter=retargeter)
    clock = FakeClock()
    backend = SimBackend(config, clock=clock.now)
    loop = ControlLoop(
        step, source, backend, settings, record=True, clock=clock.now, sleep=clock.sleep
    )
    return loop, loop.run()


def _ramp_steps(loop: ControlLoop, result: LoopResult, t_ramp: float, start_q: np.ndarray,
                window_s: float) -> np.ndarray:  # fmt: skip
    """Per-tick |Δq| / (v_max · period) of the commands in [t_ramp, t_ramp + window_s)."""
    log = result.log
    i0 = next(i for i, e in enumerate(log) if e.t_s >= t_ramp)
    i1 = next((i for i, e in enumerate(log) if e.t_s >= t_ramp + window_s), len(log))
    prev = start_q if i0 == 0 else log[i0 - 1].q
    q = np.array([prev] + [e.q for e in log[i0:i1]])
    return np.abs(np.diff(q, axis=0)) / (loop.config.max_velocity * loop.period_s)


def test_start_moves_at_the_ramp_speed_then_tracks(
    robot: tuple[RobotConfig, Retargeter], copy_model: LoadedModel, motion: HumanMotion
) -> None:
    config = robot[0]
    settings = LoopSettings(duration_s=4.5)
    loop, result = _run(robot, copy_model, ScriptedSource(motion), settings)
    modes = [m for _, m in result.transitions]
    assert modes[0] is Mode.RAMP_IN
    assert Mode.TRACKING in modes
    t_ramp = result.transitions[0][0]
    fraction = _ramp_steps(loop, result, t_ramp, config.init_pose, settings.ramp_min_s)
    assert len(fraction) >= int(settings.ramp_min_s / loop.period_s) - 1
    assert fraction.max() <= settings.ramp_speed_fraction * (1 + 1e-9)
    # The robot did move (the demo's first pose is not the init crouch) ...
    assert fraction.max() > 0.9 * settings.ramp_speed_fraction
    # ... and tracking went on at the motion's own speed after the hand-over.
    t_track = result.transitions[modes.index(Mode.TRACKING)][0]
    assert t_track >= t_ramp + settings.ramp_min_s
    after = _ramp_steps(loop, result, t_track, result.log[0].q, 3.0)
    assert after.max() <= 1 + 1e-9
    assert result.safety.commands_clipped == 0


def test_return_from_the_safe_pose_moves_at_the_ramp_speed(
    robot: tuple[RobotConfig, Retargeter], copy_model: LoadedModel, motion: HumanMotion
) -> None:
    config = robot[0]
    settings = LoopSettings(hold_after_s=0.2, safe_after_s=0.8, duration_s=6.0)
    source = ScriptedSource(motion, gaps=((1.2, 4.5),))
    loop, result = _run(robot, copy_model, source, settings)
    modes = [m for _, m in result.transitions]
    i_safe = modes.index(Mode.SAFE)
    assert modes[i_safe + 1] is Mode.RAMP_IN, modes
    safe_log = [e for e in result.log if e.mode is Mode.SAFE]
    np.testing.assert_allclose(safe_log[-1].q, config.safe_pose, atol=1e-9)  # it got there
    t_back = result.transitions[i_safe + 1][0]
    fraction = _ramp_steps(loop, result, t_back, config.safe_pose, settings.ramp_min_s)
    assert fraction.max() <= settings.ramp_speed_fraction * (1 + 1e-9)
    assert fraction.max() > 0.9 * settings.ramp_speed_fraction
    assert Mode.TRACKING in modes[i_safe + 1 :]


def test_a_hold_during_the_ramp_ramps_again(
    robot: tuple[RobotConfig, Retargeter], copy_model: LoadedModel, motion: HumanMotion
) -> None:
    settings = LoopSettings(hold_after_s=0.2, safe_after_s=1.5, duration_s=2.5)
    source = ScriptedSource(motion, gaps=((0.2, 0.7),))  # silent 0.5 s inside the ramp
    loop, result = _run(robot, copy_model, source, settings)
    modes = [m for _, m in result.transitions]
    assert modes[:3] == [Mode.RAMP_IN, Mode.HOLD, Mode.RAMP_IN], modes
    t_back = result.transitions[2][0]
    fraction = _ramp_steps(loop, result, t_back, result.log[0].q, settings.ramp_min_s)
    assert fraction.max() <= settings.ramp_speed_fraction * (1 + 1e-9)


def test_ramp_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="ramp_min_s"):
        LoopSettings(ramp_min_s=-0.1)
    with pytest.raises(ValueError, match="ramp_min_s"):
        LoopSettings(ramp_min_s=3.0, ramp_timeout_s=3.0)


class _TickBackend(SimBackend):
    """The simulator with a servo's tick grid, as the Dynamixel backend writes goals."""

    def __init__(self, config: RobotConfig, **kwargs: object) -> None:
        from robot_retarget.robot.servo_units import ServoUnits

        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        self._units = ServoUnits(config)

    @property
    def position_quantum_rad(self) -> np.ndarray:
        return np.asarray(self._units.rad_per_tick)

    def rounded(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self._units.from_ticks(self._units.to_ticks(q)))


def test_the_ramp_keeps_its_fraction_on_the_servos_tick_grid(
    robot: tuple[RobotConfig, Retargeter], copy_model: LoadedModel, motion: HumanMotion
) -> None:
    """Goals rounded to the nearest tick had stepped half a tick past the ramp's step, the
    first command from the servos' own pose most (demo on Poppy: 26 % for 25 %)."""
    config, retargeter = robot
    settings = LoopSettings(duration_s=1.5)
    source = ScriptedSource(motion)
    step = RetargetStep(config, copy_model, source.skeleton, retargeter=retargeter)
    clock = FakeClock()
    backend = _TickBackend(config, clock=clock.now)
    loop = ControlLoop(
        step, source, backend, settings, record=True, clock=clock.now, sleep=clock.sleep
    )
    result = loop.run()
    t_ramp = result.transitions[0][0]
    start = backend.rounded(np.asarray(config.init_pose))  # where tick servos report it
    fraction = _ramp_steps(loop, result, t_ramp, start, settings.ramp_min_s)
    assert fraction.max() <= settings.ramp_speed_fraction * (1 + 1e-9)
    assert fraction.max() > 0.9 * settings.ramp_speed_fraction
