"""What reaches the servos near the joint limits: ticks rounded inward (no goal a hair past a
limit), and torque switched on only where the joints are inside their limits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.safety import SafetyLayer, UnsafeCommandError
from robot_retarget.hardware.types import JointCommand
from robot_retarget.pipeline.recorder import RecordingBackend
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.robot.servo_units import ServoUnits
from robot_retarget.sim.robot_bus import SimulatedRobotBus


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_the_limit_ticks_are_the_outermost_ticks_inside_the_limits(robot: str) -> None:
    config = load_robot_config(robot)
    units = ServoUnits(config)
    eps = 1e-12
    for end, outward in ((units.limit_lo_tick, -1), (units.limit_hi_tick, 1)):
        q = units.from_ticks(end)
        assert np.all((q >= config.lower - eps) & (q <= config.upper + eps))
        beyond = np.clip(end + outward, 0, units.max_tick)
        q_out = units.from_ticks(beyond)
        moved = beyond != end
        outside = (q_out < config.lower - eps) | (q_out > config.upper + eps)
        assert np.all(outside[moved])  # one more tick would leave the limits


def _goals(sim_config: RobotConfig, rest: np.ndarray) -> tuple[list[np.ndarray], str | None]:
    """Every goal vector the backend writes on a first command from ``rest``, and the error."""
    with SimulatedRobotBus(sim_config, rest) as sim:
        backend = sim.backend()
        written: list[np.ndarray] = []
        write = backend._write_goals

        def record(group: object, ticks: np.ndarray) -> None:
            written.append(backend.units.from_ticks(ticks))
            write(group, ticks)  # type: ignore[arg-type]

        backend._write_goals = record  # type: ignore[method-assign]
        safety = SafetyLayer(sim_config, backend)
        safety.connect()
        try:
            safety.send(JointCommand(sim_config.init_pose, 1.0 / sim_config.control_rate_hz))
            return written, None
        except UnsafeCommandError as exc:
            return written, str(exc)
        finally:
            safety.disconnect()


def test_torque_is_not_switched_on_at_a_joint_past_its_limit() -> None:
    """A knee resting 0.25 rad past its limit (moved by hand, or a config whose zero offset is
    wrong): one error naming it, and no goal written at all."""
    config = load_robot_config("poppy_humanoid")
    j = config.joint_index("l_knee_y")
    rest = config.init_pose.copy()
    rest[j] = config.upper[j] + 0.25
    written, error = _goals(config, rest)
    assert error is not None
    assert "l_knee_y at" in error
    assert "move them inside by hand" in error
    assert written == []


def test_a_joint_resting_a_hair_past_its_limit_is_held_at_the_limit() -> None:
    config = load_robot_config("poppy_humanoid")
    j = config.joint_index("l_knee_y")
    rest = config.init_pose.copy()
    rest[j] = config.upper[j] + 0.01
    written, error = _goals(config, rest)
    assert error is None
    assert written
    for goal in written:
        assert np.all((goal >= config.lower - 1e-12) & (goal <= config.upper + 1e-12))


class _TickBackend(RecordingBackend):
    """Records commands and rounds them as ``rounder`` (a DynamixelBackend) writes them."""

    def __init__(self, config: RobotConfig, rounder: DynamixelBackend) -> None:
        super().__init__(config)
        self.rounder = rounder

    @property
    def position_quantum_rad(self) -> np.ndarray:
        return self.rounder.position_quantum_rad

    def rounded(self, q: np.ndarray) -> np.ndarray:
        return self.rounder.rounded(q)


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
@pytest.mark.parametrize("share", [1.0, 0.25])  # a full control period; a wake-on-input tick
def test_rounded_goals_keep_to_the_velocity_limit(robot: str, share: float) -> None:
    """Commands pulled to the step bound every time, rounded to ticks on the way out (the
    backend's own code): no tick step is more than v_max · dt (it was up to 1.16× before the
    SafetyLayer kept the rounded goals within it), and every command is on the servo's grid."""
    config = load_robot_config(robot)
    backend = DynamixelBackend(
        config,
        {
            b.name: DynamixelBus("/dev/null", protocol=b.protocol, baud_rate=b.baud_rate)
            for b in config.buses
        },
    )
    safety = SafetyLayer(config, _TickBackend(config, backend))
    safety.connect()
    rng = np.random.default_rng(0)
    dt = share / config.control_rate_hz
    prev = backend._ticks_from_rad(safety.read_state().q)
    for k in range(1, 400):
        q = safety.send(JointCommand(rng.uniform(config.lower, config.upper), k * dt)).q
        ticks = backend._ticks_from_rad(q)
        np.testing.assert_array_equal(backend._rad_from_ticks(ticks), q)  # written as it is
        step = np.abs(ticks - prev) * backend.units.rad_per_tick
        bound = config.max_velocity * (dt if k > 1 else 1.0 / config.control_rate_hz)
        assert np.all(step <= bound + 1e-12)  # the first command: a full period, by design
        prev = ticks


def test_a_rate_too_high_for_whole_ticks_is_refused() -> None:
    """At 1000 Hz an AX-12A joint moves barely one tick per period at its velocity limit: the
    safety layer in front of a tick-rounding backend names it and the rate that works."""
    config = load_robot_config("poppy_humanoid")
    backend = DynamixelBackend(
        config,
        {
            b.name: DynamixelBus("/dev/null", protocol=b.protocol, baud_rate=b.baud_rate)
            for b in config.buses
        },
    )
    fast = dataclasses.replace(config, control_rate_hz=1000.0)
    with pytest.raises(UnsafeCommandError, match=r"at 1000 Hz joint head_\w+ moves .* Hz or less"):
        SafetyLayer(fast, _TickBackend(fast, backend))
