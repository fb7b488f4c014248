"""rad ↔ ticks for every servo model and every joint's direction / zero offset of the configs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import ServoRangeError
from robot_retarget.robot.config import JointConfig, RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.robot.servo_units import JointServoUnits, ServoUnits, joint_rad_range

CONFIGS = {name: load_robot_config(name) for name in ("op3", "poppy_humanoid")}
JOINTS = [(name, j) for name, c in CONFIGS.items() for j in c.joints]
JOINT_IDS = [f"{name}.{j.name}" for name, j in JOINTS]


def test_every_model_is_covered() -> None:
    assert {j.servo_model for _, j in JOINTS} == {"XM430-W350", "MX-28", "MX-64", "AX-12A"}
    assert {j.direction for _, j in JOINTS} == {-1, 1}
    assert any(j.zero_offset_rad != 0 for _, j in JOINTS)


@pytest.mark.parametrize(("robot", "joint"), JOINTS, ids=JOINT_IDS)
@settings(max_examples=25)
@given(data=st.data())
def test_rad_tick_round_trip(robot: str, joint: JointConfig, data: st.DataObject) -> None:
    units = JointServoUnits(joint)
    lo, hi = joint_rad_range(joint)
    q = data.draw(st.floats(lo, hi, allow_nan=False), label="q")
    tick = units.to_tick(q)
    assert units.tick_range[0] <= tick <= units.tick_range[1]
    assert abs(units.from_tick(tick) - q) <= 0.5 * units.model.rad_per_tick + 1e-12
    t = data.draw(st.integers(*units.tick_range), label="tick")
    assert units.to_tick(units.from_tick(t)) == t


@pytest.mark.parametrize(("robot", "joint"), JOINTS, ids=JOINT_IDS)
def test_out_of_range_raises(robot: str, joint: JointConfig) -> None:
    units = JointServoUnits(joint)
    lo, hi = joint_rad_range(joint)
    step = units.model.rad_per_tick
    for q in (lo - step, hi + step, math.nan, math.inf):
        with pytest.raises(ServoRangeError) as info:
            units.to_tick(q)
        assert info.value.joint == joint.name
        assert info.value.unit == "rad"
        assert info.value.valid_range == (lo, hi)
    for t in (-1, units.tick_range[1] + 1):
        with pytest.raises(ServoRangeError) as info:
            units.from_tick(t)
        assert info.value.value == t
        assert info.value.unit == "tick"


def test_known_ticks() -> None:
    op3 = ServoUnits(CONFIGS["op3"])
    np.testing.assert_array_equal(op3.to_ticks(np.zeros(20)), 2048)
    q = np.zeros(20)
    q[0] = math.pi / 2
    assert op3.to_ticks(q)[0] == 2048 + 1024
    poppy = CONFIGS["poppy_humanoid"]
    units = ServoUnits(poppy)
    ticks = units.to_ticks(np.zeros(poppy.num_joints))
    assert ticks[poppy.joint_index("head_z")] == 512  # AX-12A centre
    # head_y: indirect, pypot offset 20° → servo at −20° = 512 − 20 / (300/1024) ticks.
    assert ticks[poppy.joint_index("head_y")] == round(512 - 20 * 1024 / 300)
    # l_shoulder_y: direct, offset 90° → a quarter turn above the centre.
    assert ticks[poppy.joint_index("l_shoulder_y")] == 2048 + 1024


@settings(max_examples=30)
@given(seed=st.integers(0, 2**32 - 1), robot=st.sampled_from(sorted(CONFIGS)))
def test_vector_matches_per_joint(seed: int, robot: str) -> None:
    config: RobotConfig = CONFIGS[robot]
    units = ServoUnits(config)
    rng = np.random.default_rng(seed)
    q = rng.uniform(units.lower_rad, units.upper_rad, size=(3, config.num_joints))
    ticks = units.to_ticks(q)
    assert ticks.shape == (3, config.num_joints)
    assert ticks.dtype == np.int64
    for row_q, row_t in zip(q, ticks, strict=True):
        assert list(row_t) == [u.to_tick(v) for u, v in zip(units.joints, row_q, strict=True)]
    back = units.from_ticks(ticks)
    assert np.all(np.abs(back - q) <= 0.5 * units.rad_per_tick + 1e-12)
    np.testing.assert_array_equal(units.to_ticks(back), ticks)


def test_vector_out_of_range_names_the_joint() -> None:
    config = CONFIGS["poppy_humanoid"]
    units = ServoUnits(config)
    q = np.zeros((2, config.num_joints))
    j = config.joint_index("head_y")
    q[1, j] = math.radians(200)
    with pytest.raises(ServoRangeError) as info:
        units.to_ticks(q)
    assert info.value.joint == "head_y"
    assert info.value.value == pytest.approx(math.radians(200))
    ticks = units.to_ticks(np.zeros(config.num_joints))
    ticks[j] = 1024  # one past the AX-12A's last tick
    with pytest.raises(ServoRangeError, match="head_y"):
        units.from_ticks(ticks)
    with pytest.raises(TypeError, match="integers"):
        units.from_ticks(ticks.astype(float))
    with pytest.raises(ValueError, match="last axis"):
        units.to_ticks(np.zeros(3))


def test_velocity_steps() -> None:
    config = CONFIGS["op3"]
    units = ServoUnits(config)
    v = config.max_velocity  # 46 rpm
    steps = units.velocity_to_steps(v)
    np.testing.assert_array_equal(steps, round(46 / 0.229))
    back = units.velocity_from_steps(steps)
    assert np.all(np.abs(back - v) <= 0.5 * units.velocity_step_rad_s)
    np.testing.assert_array_equal(units.velocity_to_steps(np.zeros(20)), 1)  # 0 = "no limit"
    with pytest.raises(ServoRangeError, match="speed"):
        units.velocity_to_steps(np.full(20, 100.0))
