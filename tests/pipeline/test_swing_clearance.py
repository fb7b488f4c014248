"""Swing feet lifted to the performer's height (robot_retarget.pipeline.swing_clearance)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.motion.human_motion import load_motion
from robot_retarget.pipeline import swing_clearance as sc
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.defaults import default_model_name
from robot_retarget.pipeline.floating_base import (
    planted_feet,
    swing_scuff_share,
    swing_scuffs,
    trajectory_feet,
)
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config

OP3 = load_robot_config("op3")


@pytest.mark.parametrize(
    ("robot", "joints"),
    [("op3", ("l_ank_pitch", "r_ank_pitch")), ("poppy_humanoid", ("l_ankle_y", "r_ankle_y"))],
)
def test_each_foot_turns_about_its_ankle_pitch_joint(robot: str, joints: tuple[str, str]) -> None:
    config = load_robot_config(robot)
    feet = sc.robot_foot_pitches(config)
    assert tuple(config.joints[feet[s].joint].name for s in ("Left", "Right")) == joints


def _lowest(config: RobotConfig, q: np.ndarray, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    points = sc.robot_foot_pitches(config)["Left"].points
    base = sc.base_transforms(pos, rot)
    return RobotKinematics(config).frame_positions(q, points, base)[..., 2].min(axis=-1)


def _toe_down(frames: int, pitch: float, low_m: float) -> tuple[np.ndarray, ...]:
    """OP3 at its init pose with the left ankle pitched toe-down by ``pitch`` (rad;
    l_ank_pitch < 0), on an upright base that puts the left foot's lowest point ``low_m``
    above the floor: (q, base position, base rotation)."""
    q = np.tile(np.asarray(OP3.init_pose, dtype=np.float64), (frames, 1))
    j = [jc.name for jc in OP3.joints].index("l_ank_pitch")
    q[:, j] = np.clip(q[:, j] - pitch, OP3.lower[j], OP3.upper[j])
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (frames, 1))
    pos = np.zeros((frames, 3))
    pos[:, 2] = low_m - _lowest(OP3, q, pos, rot)
    return q, pos, rot


def test_a_toe_down_foot_is_lifted_by_its_ankle_only() -> None:
    frames = 40
    q, pos, rot = _toe_down(frames, 0.6, 0.002)  # the toe 2 mm above the floor; want 15 mm
    wanted = {"Left": np.full(frames, 0.015), "Right": np.full(frames, -np.inf)}
    feet = sc.robot_foot_pitches(OP3)
    out = sc.lift_swing_feet(OP3, q, pos, rot, wanted, feet, 125.0)
    j = feet["Left"].joint
    others = [k for k in range(OP3.num_joints) if k != j]
    np.testing.assert_array_equal(out[:, others], q[:, others])
    low = _lowest(OP3, out, pos, rot)
    assert low[frames // 2 :].min() >= 0.015 - 1e-3  # after the speed-limited start
    assert np.all(np.abs(np.diff(out[:, j])) <= OP3.max_velocity[j] / 125.0 + 1e-12)


def test_a_foot_high_enough_is_left_alone() -> None:
    frames = 10
    q, pos, rot = _toe_down(frames, 0.3, 0.03)
    wanted = {"Left": np.full(frames, 0.02), "Right": np.full(frames, 0.02)}
    out = sc.lift_swing_feet(OP3, q, pos, rot, wanted, sc.robot_foot_pitches(OP3), 125.0)
    np.testing.assert_array_equal(out, q)


@settings(max_examples=30, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.floats(0.0, 0.08),
)
def test_lifting_never_leaves_limits_or_speed(seed: int, wanted_m: float) -> None:
    rng = np.random.default_rng(seed)
    frames = 30
    lo, hi = np.asarray(OP3.lower), np.asarray(OP3.upper)
    step = np.asarray(OP3.max_velocity) / 125.0
    q = np.empty((frames, OP3.num_joints))
    q[0] = rng.uniform(lo, hi)
    for t in range(1, frames):  # a trajectory inside the limits and the speed limit
        q[t] = np.clip(q[t - 1] + rng.uniform(-step, step), lo, hi)
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (frames, 1))
    pos = np.zeros((frames, 3))
    pos[:, 2] = rng.uniform(0.2, 0.4)
    wanted = {"Left": np.full(frames, wanted_m), "Right": np.full(frames, wanted_m)}
    out = sc.lift_swing_feet(OP3, q, pos, rot, wanted, sc.robot_foot_pitches(OP3), 125.0)
    assert np.all(out >= lo - 1e-12)
    assert np.all(out <= hi + 1e-12)
    assert np.all(np.abs(np.diff(out, axis=0)) <= step + 1e-12)


def test_a_turn_is_held_where_it_is_needed_and_reached_within_the_speed_limit() -> None:
    column = np.zeros(15)
    turns = np.r_[np.zeros(6), np.ones(3), np.zeros(6)]
    held = sc.held_turns(column, turns, 0.25)
    assert np.all(held[6:9] >= 1.0)  # the whole turn wherever it is needed
    assert held[2] == 0.0  # reached from 0 in four steps of 0.25, no earlier
    assert np.all(np.abs(np.diff(held)) <= 0.25 + 1e-12)
    assert held[0] == 0.0
    assert held[-1] == 0.0
    # A negative turn is held the other way; the column elsewhere is left as it is.
    assert np.all(sc.held_turns(column, -turns, 0.25)[6:9] <= -1.0)
    # Frames kept as they are (a planted foot) win: the turn ramps within the others.
    kept = np.r_[np.ones(5, dtype=bool), np.zeros(10, dtype=bool)]
    held = sc.held_turns(column, turns, 0.25, kept)
    assert np.all(held[:5] == 0.0)
    assert held[5] == 0.25
    assert held[6] == 0.5
    assert np.all(np.abs(np.diff(held)) <= 0.25 + 1e-12)
    smoothed = sc.smooth(np.r_[np.zeros(20), np.ones(20)], 125.0)
    assert np.all(np.diff(smoothed) >= 0.0)
    assert smoothed[0] == 0.0
    assert smoothed[-1] == pytest.approx(1.0)


def test_a_stance_is_kept_but_for_its_ends() -> None:
    mask = np.array([1, 1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1], dtype=bool)
    deep = sc._deep_in(mask, 2.0)
    np.testing.assert_array_equal(deep, [1, 1, 1, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(sc._deep_in(mask, 0.0), mask)


def test_a_lift_is_no_faster_than_the_limit_where_the_clip_was_not() -> None:
    """A clip at 30 Hz that itself jumps once (3 steps' worth, frame 70): the lift in frames
    20-40 moves at most one step a frame, wherever it starts or ends."""
    frames, fps = 100, 30.0
    q, pos, rot = _toe_down(frames, 0.6, 0.002)
    j = [jc.name for jc in OP3.joints].index("l_ank_pitch")
    step = OP3.max_velocity[j] / fps
    q[70:, j] -= 3.0 * step
    wanted = np.full(frames, -np.inf)
    wanted[20:40] = 0.02
    out = sc.lift_swing_feet(
        OP3, q, pos, rot, {"Left": wanted}, {"Left": sc.robot_foot_pitches(OP3)["Left"]}, fps
    )
    bound = np.maximum(step, np.abs(np.diff(q[:, j])))
    assert np.all(np.abs(np.diff(out[:, j])) <= bound + 1e-12)
    assert np.abs(out[:, j] - q[:, j]).max() > 0.1  # it did lift


def test_the_total_turn_from_the_solved_angle_is_capped() -> None:
    frames = 20
    solved, pos, rot = _toe_down(frames, 0.3, 0.002)
    j = [jc.name for jc in OP3.joints].index("l_ank_pitch")
    q = solved.copy()
    q[:, j] -= 0.7  # an earlier pass turned it already (the wrong way: further down)
    wanted = {"Left": np.full(frames, 0.2), "Right": np.full(frames, -np.inf)}
    out = sc.lift_swing_feet(
        OP3, q, pos, rot, wanted, sc.robot_foot_pitches(OP3), 125.0, solved=solved
    )
    assert np.abs(out[:, j] - solved[:, j]).max() <= sc.MAX_TURN_RAD + 1e-12


def test_an_ankle_is_chosen_over_a_toe_joint_listed_before_it() -> None:
    """A toe joint at the ball of OP3's left foot, with the same lateral axis, carrying the toe
    point (so the toe is the foot's only point) and listed first: the ankle, which turns more
    of the robot, is still the pitch joint."""
    pitch = next(jc for jc in OP3.joints if jc.name == "l_ank_pitch")
    toe = next(f for f in OP3.frames if f.name == "l_toe")
    toe_joint = dataclasses.replace(
        pitch,
        name="l_toe_pitch",
        parent_link=toe.parent_link,
        child_link="l_toe_link",
        origin_xyz=(toe.origin_xyz[0] - 0.04, toe.origin_xyz[1], toe.origin_xyz[2]),
        origin_rpy=(0.0, 0.0, 0.0),
        servo_id=99,
    )
    frames = tuple(
        dataclasses.replace(f, parent_link="l_toe_link", origin_xyz=(0.04, 0.0, 0.0))
        if f.name == "l_toe"
        else f
        for f in OP3.frames
    )
    config = dataclasses.replace(
        OP3,
        joints=(toe_joint, *OP3.joints),
        frames=frames,
        init_pose=np.r_[0.0, OP3.init_pose],
        safe_pose=np.r_[0.0, OP3.safe_pose],
    )
    feet = sc.robot_foot_pitches(config)
    assert config.joints[feet["Left"].joint].name == "l_ank_pitch"


def test_swing_scuff_share_counts_single_support_swing_frames() -> None:
    # OP3 foot points: l_sole, r_sole, l_toe, r_toe, l_heel, r_heel.
    feet = np.zeros((4, 6, 3))
    feet[:, [0, 2, 4], 2] = [[0.005], [0.02], [0.02], [0.005]]  # left foot: low, high, high, low
    planted = np.zeros((4, 6), dtype=bool)
    planted[:, [1, 3, 5]] = True  # the performer stands on the right foot throughout
    assert swing_scuff_share(OP3, feet, planted) == pytest.approx(0.5)
    assert swing_scuffs(OP3, feet, planted) == (2, 4)
    assert swing_scuff_share(OP3, feet, np.zeros((4, 6), dtype=bool)) is None


def test_op3_swing_foot_clears_the_floor_on_a_real_walk(shared_data_dir: Path) -> None:
    """CMU 02_01 (a training subject's walk): the share of swing frames with the lifted foot
    within 1 cm of the floor falls (0.65 → 0.23 measured), and only the ankles' pitch joints
    differ from the trajectory as solved (``lift_swing_feet=False``, as ``stream`` sends it)."""
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh")
    step = RetargetStep(OP3, default_model_name(), motion.skeleton)
    lifted, plain = (
        convert_motion(
            motion, step, whole_clip_branches=True, lift_swing_feet=lift, hold_double_support=False
        ).trajectory
        for lift in (True, False)
    )
    m = motion.resample(lifted.fps)
    planted = planted_feet(OP3, m.positions(), m.fps)
    shares = []
    for traj in (plain, lifted):
        assert traj.root_pos is not None
        assert traj.root_quat is not None
        feet = trajectory_feet(OP3, traj.q, traj.root_pos, traj.root_quat)
        shares.append(swing_scuff_share(OP3, feet, planted))
    before, after = shares
    assert before is not None
    assert after is not None
    assert after < 0.6 * before
    moved = np.flatnonzero(np.abs(lifted.q - plain.q).max(axis=0) > 0)
    assert {OP3.joints[j].name for j in moved} <= {"l_ank_pitch", "r_ank_pitch"}
