"""Feet turned level about their long axis (robot_retarget.optimize.level_feet)."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import ConfigError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.optimize import Retargeter
from robot_retarget.optimize.level_feet import (
    FADE_FULL,
    FADE_START,
    FEET,
    FootLevel,
    level_globals,
    level_twists,
    level_twists_sx,
    rest_axes_of,
)
from robot_retarget.optimize.targets import FrameTargetBuilder, targets_from_rotations
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.retarget_settings import RetargetSettings
from robot_retarget.skeleton.canonical import Joint, default_canonical_skeleton

UP = np.array([0.0, 1.0, 0.0])
LEFT = np.array([1.0, 0.0, 0.0])
REST_AXIS = np.array([0.0, -0.35, 0.94]) / np.linalg.norm([0.0, -0.35, 0.94])  # heel → toe

unit_quats = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.2
)


def _lateral(g: np.ndarray) -> np.ndarray:
    x = LEFT - (LEFT @ REST_AXIS) * REST_AXIS
    return quat.rotate(g, x / np.linalg.norm(x))


def _sine(g: np.ndarray) -> float:
    return float(np.linalg.norm(np.cross(UP, quat.rotate(g, REST_AXIS))))


@settings(max_examples=200, deadline=None)
@given(unit_quats)
def test_the_long_axis_stays_and_a_foot_far_from_vertical_ends_level(v: list[float]) -> None:
    g = quat.normalize(np.array(v))
    turned = quat.mul(level_twists(g, REST_AXIS, 1.0), g)
    axis = quat.rotate(g, REST_AXIS)
    np.testing.assert_allclose(quat.rotate(turned, REST_AXIS), axis, atol=1e-9)
    level = np.cross(UP, axis)
    level /= max(np.linalg.norm(level), 1e-12)
    roll = np.degrees(np.arccos(np.clip(_lateral(g) @ level, -1.0, 1.0)))
    if _sine(g) >= FADE_FULL and roll <= 45.0:  # a rig-sized roll, far from vertical
        lateral = _lateral(turned)
        assert abs(lateral @ UP) < 1e-9  # horizontal
        assert lateral @ level > 0.0  # the foot's left, not its right: upright


@pytest.mark.parametrize("from_vertical_deg", [0.0, 5.0, 17.0])
@pytest.mark.parametrize("roll_deg", [-30.0, 0.0, 20.0])
def test_a_foot_near_vertical_is_left_as_it_is(from_vertical_deg: float, roll_deg: float) -> None:
    # Pitch the rest foot until its long axis is from_vertical_deg off straight down, then roll.
    down = np.arccos(np.clip(REST_AXIS @ -UP, -1.0, 1.0))
    pitch = quat.from_axis_angle(LEFT, down - np.radians(from_vertical_deg))
    g = quat.mul(quat.from_axis_angle(quat.rotate(pitch, REST_AXIS), np.radians(roll_deg)), pitch)
    assert _sine(g) == pytest.approx(np.sin(np.radians(from_vertical_deg)), abs=1e-9)
    np.testing.assert_allclose(level_twists(g, REST_AXIS, 1.0), quat.identity(), atol=1e-12)


@pytest.mark.parametrize(
    ("roll_deg", "turned_deg"),
    [(5.0, 5.0), (-20.0, -20.0), (45.0, 45.0), (60.0, 40.0), (-75.0, -25.0), (90.0, 0.0),
     (150.0, 0.0), (180.0, 0.0)],
)  # fmt: skip
def test_the_share_of_a_rig_sized_roll_is_removed(roll_deg: float, turned_deg: float) -> None:
    """Up to 45° the whole roll times the share; from 90° (a foot pitched back past vertical
    is rolled 180° by construction) nothing; linearly between."""
    roll = quat.from_axis_angle(REST_AXIS, np.radians(roll_deg))
    for share in (0.0, 0.5, 1.0):
        twist = level_twists(roll, REST_AXIS, share)
        left = np.degrees(quat.angle_between(quat.mul(twist, roll), quat.identity()))
        assert left == pytest.approx(abs(roll_deg - share * turned_deg), abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(unit_quats, st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))
def test_a_small_move_of_the_foot_moves_the_level_foot_little(
    v: list[float], direction: list[float]
) -> None:
    """No jump anywhere (the roll's ±180° cut, the fades): 1 mrad in, at most 20 mrad out."""
    g = quat.normalize(np.array(v))
    d = np.array(direction)
    if np.linalg.norm(d) < 1e-3:
        return
    nudged = quat.mul(quat.from_axis_angle(d / np.linalg.norm(d), 1e-3), g)
    a, b = (quat.mul(level_twists(q, REST_AXIS, 1.0), q) for q in (g, nudged))
    assert quat.angle_between(a, b) < 0.02


def test_symbolic_turns_match_numpy_in_every_regime() -> None:
    rng = np.random.default_rng(4)
    # Not of unit length, as a network's or a sum's rotations may be: both normalise first.
    g = quat.normalize(rng.normal(size=(600, 2, 4))) * rng.uniform(0.5, 2.0, size=(600, 2, 1))
    level = FootLevel.of_axes(np.stack([REST_AXIS, REST_AXIS * [-1, 1, 1]]), 0.8)
    sym = [ca.SX.sym(f"g{k}", 4) for k in range(2)]
    twists = level_twists_sx(level, [tuple(s[i] for i in range(4)) for s in sym])
    fn = ca.Function("t", sym, [ca.vertcat(*t) for t in twists])
    axis = quat.rotate(quat.normalize(g), level.rest_axes)
    sines = np.linalg.norm(np.cross(UP, axis), axis=-1)
    assert (sines < FADE_START).any()  # all three regimes of the foot's angle from vertical
    assert (sines > FADE_FULL).any()
    assert ((sines > FADE_START) & (sines < FADE_FULL)).any()
    ref = level_twists(g, level.rest_axes, 0.8)
    np.testing.assert_allclose(np.linalg.norm(ref, axis=-1), 1.0, atol=1e-12)
    turns = 2.0 * np.arccos(np.clip(np.abs(ref[..., 0]), 0.0, 1.0))
    assert (turns > np.radians(10.0)).sum() > 50  # turns of every size were compared
    for t in range(len(g)):
        got = np.hstack([np.asarray(r).ravel() for r in fn(g[t, 0], g[t, 1])])
        np.testing.assert_allclose(got, ref[t].ravel(), atol=1e-12)


def test_a_zero_quaternion_or_toe_offset_does_not_raise() -> None:
    np.testing.assert_allclose(level_twists(np.zeros(4), REST_AXIS, 1.0), quat.identity())
    offsets = np.array(default_canonical_skeleton().offsets)
    for _foot, toe in FEET:
        offsets[toe] = 0.0
    level = FootLevel.of_skeleton(offsets, 1.0)
    np.testing.assert_allclose(np.linalg.norm(level.rest_axes, axis=-1), 1.0)


@pytest.mark.parametrize("bad", [-0.5, 1.5, float("nan")])
def test_every_path_refuses_a_share_outside_0_to_1(bad: float, op3: RobotConfig) -> None:
    retargeter = Retargeter(op3)
    skeleton = robot_canonical_skeleton(op3)
    with pytest.raises(ValueError, match="level_feet must be a share 0 … 1"):
        FrameTargetBuilder(retargeter.problem, skeleton, level_feet=bad)
    with pytest.raises(ValueError, match="level_feet must be a share 0 … 1"):
        targets_from_rotations(retargeter.problem, skeleton, quat.identity((1, 22)), level_feet=bad)


def test_the_live_path_levels_as_the_numpy_path(op3: RobotConfig) -> None:
    """The compiled frame program against the numpy targets and writers, on the demo with its
    feet rolled 30° and 70° (inside and beyond the roll's fade) at a share of 0.6."""
    config = dataclasses.replace(op3, retarget={**op3.retarget, "level_feet": 0.6})
    motion = demo_motion(fps=config.control_rate_hz).frames(0, 60)
    skeleton = robot_canonical_skeleton(config)
    axes = FootLevel.of_skeleton(skeleton.offsets, 1.0).rest_axes
    local = np.array(motion.local_quats)
    for (foot, _toe), axis, roll in zip(FEET, axes, (30.0, -70.0), strict=True):
        local[:, foot] = quat.mul(local[:, foot], quat.from_axis_angle(axis, np.radians(roll)))
    dt = 1.0 / config.control_rate_hz
    fast, ref = (
        RetargetStep(config, "copy", motion.skeleton, frame_program=program)
        for program in (True, False)
    )
    as_given = dataclasses.replace(config, retarget={**config.retarget, "level_feet": 0.0})
    flat = RetargetStep(as_given, "copy", motion.skeleton)
    for s in (fast, ref, flat):
        s.reset()
    moved = 0.0
    for t in range(motion.num_frames):
        a = fast(local[t], motion.root_pos[t], dt)
        b = ref(local[t], motion.root_pos[t], dt)
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
        moved = max(moved, float(np.abs(a.q - flat(local[t], motion.root_pos[t], dt).q).max()))
    assert moved > np.radians(5.0)  # the share turned the ankles


def test_the_toes_turn_with_their_foot_and_nothing_else_moves() -> None:
    rng = np.random.default_rng(1)
    glob = quat.normalize(rng.normal(size=(5, 22, 4)))
    level = FootLevel.of_axes(np.stack([REST_AXIS, REST_AXIS]), 1.0)
    out = level_globals(level, glob)
    moved = {int(j) for f, t in FEET for j in (f, t)}
    for j in range(22):
        if j not in moved:
            np.testing.assert_array_equal(out[:, j], glob[:, j])
    for foot, toe in FEET:  # the toe keeps its rotation relative to its foot
        np.testing.assert_allclose(
            quat.canonical_sign(quat.mul(quat.conjugate(out[:, foot]), out[:, toe])),
            quat.canonical_sign(quat.mul(quat.conjugate(glob[:, foot]), glob[:, toe])),
            atol=1e-12,
        )


def test_rest_axes_of_a_motion_are_its_toe_offsets() -> None:
    rng = np.random.default_rng(2)
    glob = quat.normalize(rng.normal(size=(3, 22, 4)))
    pos = rng.normal(size=(3, 22, 3))
    for k, (foot, toe) in enumerate(FEET):
        pos[:, toe] = pos[:, foot] + quat.rotate(glob[:, foot], 0.12 * REST_AXIS)
        np.testing.assert_allclose(
            rest_axes_of(pos, glob)[:, k], np.tile(REST_AXIS, (3, 1)), atol=1e-12
        )


def _rolled_feet(offsets: np.ndarray, roll_deg: float) -> np.ndarray:
    """Rest rotations (22, 4) with both feet rolled ``roll_deg`` about their own long axis
    (outwards on both feet, as the CMU rigs' feet stand in stance)."""
    out = quat.identity((22,))
    axes = FootLevel.of_skeleton(offsets, 1.0).rest_axes
    for side, (foot, _toe), axis in zip((1.0, -1.0), FEET, axes, strict=True):
        out[foot] = quat.from_axis_angle(axis, side * np.radians(roll_deg))
    return out


def test_targets_of_a_rolled_foot_are_level_on_every_path(op3: RobotConfig) -> None:
    retargeter = Retargeter(op3)
    skeleton = robot_canonical_skeleton(op3)
    rest = quat.identity((22,))
    rolled = _rolled_feet(skeleton.offsets, 20.0)
    feet = [k for k, b in enumerate(retargeter.problem.bones) if b.canonical.endswith("Foot")]
    level = FrameTargetBuilder(retargeter.problem, skeleton, level_feet=1.0)
    as_given = FrameTargetBuilder(retargeter.problem, skeleton)
    at_rest = as_given(rest).normals
    rolled_normals = as_given(rolled).normals
    assert at_rest is not None
    assert rolled_normals is not None
    for targets in (
        level(rolled),
        level._numpy_call(rolled),
        targets_from_rotations(retargeter.problem, skeleton, rolled[None], level_feet=1.0).frame(0),
    ):
        assert targets.normals is not None
        np.testing.assert_allclose(targets.normals[feet], at_rest[feet], atol=1e-12)
        np.testing.assert_allclose(targets.directions, as_given(rolled).directions, atol=1e-12)
    off = np.degrees(np.arccos(np.sum(rolled_normals[feet] * at_rest[feet], -1)))
    assert off == pytest.approx([20.0, 20.0], abs=0.2)  # the rig's roll, as given


def test_op3_defaults_to_level_feet_and_the_share_is_checked(op3: RobotConfig) -> None:
    assert Retargeter(op3).settings.level_feet == 1.0
    for bad in (1.5, -0.1):
        with pytest.raises(ConfigError) as err:
            RetargetSettings.from_mapping({"level_feet": bad})
        assert err.value.key == "retarget.level_feet"
    assert RetargetSettings.from_mapping({"level_feet": 0.25}).level_feet == 0.25


def test_joint_constants_are_the_canonical_feet() -> None:
    assert [(int(f), int(t)) for f, t in FEET] == [
        (Joint.LeftFoot, Joint.LeftToeBase),
        (Joint.RightFoot, Joint.RightToeBase),
    ]
