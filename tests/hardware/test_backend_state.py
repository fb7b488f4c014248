"""What read_state reports, register by register: hardware errors, temperature, speed, load."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import ServoFaultError, ServoRangeError
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.servo_units import ServoUnits
from robot_retarget.sim.dxl_bus import SimulatedBus

MakeBuses = Callable[..., dict[str, DynamixelBus]]


def test_hardware_error_is_filled_from_the_register_for_every_faulty_servo(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    a, b = 2, 7
    with backend:
        state = backend.read_state()
        assert not state.hardware_error.any()
        for i, bits in ((a, 0x20), (b, 0x08 | 0x01)):
            j = op3.joints[i]
            op3_sim[j.bus].servos[j.servo_id].inject_hardware_error(bits)
        with pytest.raises(ServoFaultError) as info:
            backend.read_state()
        assert info.value.servo_id == op3.joints[a].servo_id
        expected = np.zeros(op3.num_joints, dtype=np.int64)
        expected[a], expected[b] = 0x20, 0x09
        np.testing.assert_array_equal(backend.hardware_error, expected)


def test_protocol1_hardware_error_bits_are_kept(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    i = poppy.num_joints - 1
    j = poppy.joints[i]
    with DynamixelBackend(poppy, make_buses(poppy, poppy_sim)) as backend:
        poppy_sim[j.bus].servos[j.servo_id].inject_hardware_error(0x04)
        with pytest.raises(ServoFaultError, match="overheating"):
            backend.read_state()
        assert backend.hardware_error[i] == 0x04
        assert np.count_nonzero(backend.hardware_error) == 1


@pytest.mark.parametrize("robot", ["op3", "poppy"])
def test_temperature_speed_and_load_decode_by_register(
    robot: str,
    op3: RobotConfig,
    poppy: RobotConfig,
    make_buses: MakeBuses,
    request: pytest.FixtureRequest,
) -> None:
    config = op3 if robot == "op3" else poppy
    sims: dict[str, SimulatedBus] = request.getfixturevalue(f"{robot}_sim")
    for k, joint in enumerate(config.joints):
        servo = sims[joint.bus].servos[joint.servo_id]
        servo._put("present_temperature", 40 + k)
        # Load: 25 % of the model's full load, one sign per joint (P1.0: bit 10 is CW).
        full = servo.table.full_load
        if servo.protocol == 2.0:
            servo._put("present_load", (-1) ** k * (full // 4))
        else:
            servo._put("present_load", full // 4 | (1024 if k % 2 else 0))
    with DynamixelBackend(config, make_buses(config, sims)) as backend:
        state = backend.read_state()
    np.testing.assert_array_equal(state.temperature, 40 + np.arange(config.num_joints))
    direction = np.array([j.direction for j in config.joints], dtype=float)
    sign = np.array([(-1) ** k for k in range(config.num_joints)], dtype=float)
    full = np.array([sims[j.bus].servos[j.servo_id].table.full_load for j in config.joints])
    np.testing.assert_allclose(state.load, direction * sign * (full // 4) / full)
    np.testing.assert_array_equal(state.velocity, 0.0)  # torque off: nothing moves
    assert state.q.shape == (config.num_joints,)


def test_temperature_is_read_about_once_a_second_on_protocol2(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    j = op3.joints[0]
    servo = op3_sim[j.bus].servos[j.servo_id]
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        servo._put("present_temperature", 55)
        seen = [backend.read_state().temperature[0] for _ in range(round(op3.control_rate_hz))]
    assert seen[-1] == 55
    assert 55 not in seen[:-2]  # not every tick: once per control_rate_hz reads


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_tick_conversions_equal_servo_units(op3: RobotConfig, data: st.DataObject) -> None:
    backend = DynamixelBackend(op3, {b.name: DynamixelBus("/dev/null", protocol=2.0,
                               baud_rate=b.baud_rate) for b in op3.buses})  # fmt: skip
    units = ServoUnits(op3)
    q = np.array(
        [
            data.draw(st.floats(lo, hi))
            for lo, hi in zip(units.lower_rad, units.upper_rad, strict=True)
        ]
    )
    # The command path's ticks are ServoUnits' inside the joint limits, and at the nearest
    # tick inside them past a limit (no tick a hair past it).
    sent = backend._ticks_from_rad(q)
    inside = (q >= op3.lower) & (q <= op3.upper)
    np.testing.assert_array_equal(sent[inside], units.to_ticks(q)[inside])
    assert np.all((sent >= units.limit_lo_tick) & (sent <= units.limit_hi_tick))
    back = backend._rad_from_ticks(sent)
    assert np.all((back >= op3.lower - 1e-12) & (back <= op3.upper + 1e-12))
    ticks = units.to_ticks(q)
    np.testing.assert_array_equal(backend._rad_from_ticks(ticks), units.from_ticks(ticks))
    bad = ticks.copy()
    bad[0] = units.max_tick[0] + 1
    with pytest.raises(ServoRangeError):
        backend._rad_from_ticks(bad)
