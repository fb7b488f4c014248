"""Feet held against each other in double support (robot_retarget.pipeline.double_support)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.motion.human_motion import load_motion
from robot_retarget.pipeline import double_support as ds
from robot_retarget.pipeline.convert import check_limits, convert_motion
from robot_retarget.pipeline.defaults import default_model_name
from robot_retarget.pipeline.floating_base import (
    floating_base,
    planted_feet,
    planted_skate_m_s,
    trajectory_feet,
)
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config

OP3 = load_robot_config("op3")


@pytest.mark.parametrize(
    ("robot", "left"),
    [
        ("op3", ("l_hip_yaw", "l_hip_roll", "l_hip_pitch", "l_knee", "l_ank_pitch", "l_ank_roll")),
        ("poppy_humanoid", ("l_hip_x", "l_hip_z", "l_hip_y", "l_knee_y", "l_ankle_y")),
    ],
)
def test_each_leg_is_the_joints_that_move_its_foot_alone(robot: str, left: tuple[str, ...]) -> None:
    config = load_robot_config(robot)
    legs = ds.robot_legs(config)
    assert tuple(config.joints[j].name for j in legs["Left"].joints) == left
    right = tuple(config.joints[j].name for j in legs["Right"].joints)
    assert right == tuple(name.replace("l_", "r_", 1) for name in left)
    assert not set(legs["Left"].columns) & set(legs["Right"].columns)


def test_a_robot_with_one_foot_has_no_legs_to_hold() -> None:
    one_foot = dataclasses.replace(
        OP3, bones=tuple(b for b in OP3.bones if not b.canonical.startswith("Right"))
    )
    assert ds.robot_legs(one_foot) == {}


@settings(max_examples=60, deadline=None)
@given(st.lists(st.booleans(), max_size=40))
def test_phases_are_the_runs_of_two_frames_or_more(flags: list[bool]) -> None:
    """Without a bridge: the runs of True, the one-frame runs left out."""
    found = ds.phases(np.array(flags, dtype=bool))
    covered = np.zeros(len(flags), dtype=bool)
    for start, stop in found:
        assert stop - start >= 2
        assert all(flags[start:stop])
        assert start == 0 or not flags[start - 1]
        assert stop == len(flags) or not flags[stop]
        covered[start:stop] = True
    # Every frame left out belongs to a run shorter than two frames.
    for t in np.flatnonzero(np.array(flags, dtype=bool) & ~covered):
        assert not (t > 0 and flags[t - 1])
        assert not (t + 1 < len(flags) and flags[t + 1])


def test_the_leg_shifts_its_foot_and_keeps_its_orientation() -> None:
    """Random leg poses around the init pose, shifted up to 1.5 cm horizontally: the foot link
    lands within 0.5 mm where no joint needs more than the largest correction (deep crouches
    do: they go part of the way) and turns under 0.1°; no other joint moves."""
    kin = RobotKinematics(OP3)
    rng = np.random.default_rng(0)
    leg = ds.robot_legs(OP3)["Right"]
    q = np.tile(np.asarray(OP3.init_pose, dtype=np.float64), (300, 1))
    q[:, leg.joints] += rng.uniform(-0.5, 0.5, (300, len(leg.joints)))
    q = np.clip(q, OP3.lower, OP3.upper)
    shift = np.zeros((300, 3))
    shift[:, :2] = rng.uniform(-0.015, 0.015, (300, 2))
    held = ds.shift_feet(kin, q, leg, shift)
    rot0, pos0 = kin.frame_poses(q, [leg.link])
    rot1, pos1 = kin.frame_poses(held, [leg.link])
    miss = np.linalg.norm(pos1[:, 0] - pos0[:, 0] - shift, axis=1)
    capped = np.abs(held - q).max(axis=1) >= ds.MAX_CORRECTION_RAD - 1e-9
    assert capped.mean() < 0.05
    assert miss[~capped].max() < 5e-4
    # A capped frame still moves its foot toward the target, not away.
    assert np.all(
        np.linalg.norm(pos1[:, 0] - pos0[:, 0] - shift, axis=1) < np.linalg.norm(shift, axis=1)
    )
    turn = np.degrees(np.linalg.norm(ds._rotation_error(rot1[:, 0], rot0[:, 0]), axis=1))
    assert turn.max() < 0.1
    others = np.setdiff1d(np.arange(OP3.num_joints), leg.joints)
    assert np.array_equal(held[:, others], q[:, others])
    assert np.abs(held - q).max() <= ds.MAX_CORRECTION_RAD + 1e-12


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-4.0, 4.0), min_size=2, max_size=30),
    st.floats(0.01, 0.5),
)
def test_rate_limited_angles_stay_inside_limits_and_speed(values: list[float], step: float) -> None:
    q = np.array(values)[:, None]
    lower, upper = np.array([-1.0]), np.array([1.5])
    out = ds._rate_limited(q, lower, upper, np.array([step]))
    assert np.all(out >= lower)
    assert np.all(out <= upper)
    assert np.all(np.abs(np.diff(out, axis=0)) <= step + 1e-12)


def test_a_short_gap_does_not_end_a_phase() -> None:
    flags = np.array([1, 1, 1, 0, 0, 1, 1, 0, 0, 0, 1, 1, 1], dtype=bool)
    assert ds.phases(flags) == [(0, 3), (5, 7), (10, 13)]
    assert ds.phases(flags, bridge=2) == [(0, 7), (10, 13)]
    assert ds.phases(flags, bridge=3) == [(0, 13)]
    assert ds.bridge_frames(125.0) == 5


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-0.01, 0.01), min_size=1, max_size=30),
    st.floats(0.5, 1.0),
)
def test_a_leaky_sum_lets_each_slide_go_at_its_rate(values: list[float], keep: float) -> None:
    slid = np.column_stack([values, np.zeros(len(values))])
    out = ds._leaky_sum(slid, keep)
    ages = np.arange(len(values))[::-1]
    assert out[-1, 0] == pytest.approx(float(np.sum(keep**ages * np.array(values))), abs=1e-12)
    assert np.allclose(ds._leaky_sum(slid, 1.0), np.cumsum(slid, axis=0))


@pytest.mark.data
@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_feet_stop_sliding_against_each_other_on_a_real_walk(
    shared_data_dir: Path, robot: str
) -> None:
    """CMU 02_01 (a training subject's walk): held, one foot's points on the floor slide
    against the other's less far per double-support phase (p90; measured OP3 1.26 → 0.71 cm,
    Poppy 1.69 → 0.81 cm), the stance feet slide less, only leg joints move, and every limit
    and speed limit holds."""
    config = load_robot_config(robot)
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh")
    step = RetargetStep(config, default_model_name(), motion.skeleton)
    results = [
        convert_motion(motion, step, whole_clip_branches=True, hold_double_support=hold)
        for hold in (False, True)
    ]
    m = motion.resample(config.control_rate_hz)
    planted = planted_feet(config, m.positions(), m.fps)
    slides, skates = [], []
    for result in results:
        traj = result.trajectory
        assert traj.root_pos is not None
        assert traj.root_quat is not None
        assert result.limits.ok
        assert check_limits(config, traj.q, 1.0 / traj.fps).ok
        feet = trajectory_feet(config, traj.q, traj.root_pos, traj.root_quat)
        slides.append(np.percentile(ds.double_support_slides(config, feet, planted, traj.fps), 90))
        skates.append(planted_skate_m_s(feet, traj.fps, planted))
    assert slides[1] < 0.7 * slides[0]
    before, after = skates
    assert before is not None
    assert after is not None
    assert after < before
    solved, held = (r.trajectory.q for r in results)
    moved = np.flatnonzero(np.abs(held - solved).max(axis=0) > 0)
    legs = np.concatenate([leg.joints for leg in ds.robot_legs(config).values()])
    assert set(moved) <= set(legs)


@pytest.mark.data
@pytest.mark.parametrize("frames", [(0, 2), (0, 9), (300, 357)])
def test_short_clips_and_a_stance_at_the_end_stay_inside_the_limits(
    shared_data_dir: Path, frames: tuple[int, int]
) -> None:
    """A clip of two frames, one shorter than the smoothing, and the end of a walk in double
    support (02_01 ends standing): every joint inside its limits and speed limit, only leg
    joints moved; a robot with one foot is returned as it came."""
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh").resample(125.0)
    motion = motion.frames(*frames)
    rng = np.random.default_rng(1)
    q = np.asarray(OP3.init_pose) + rng.normal(0.0, 0.002, (motion.num_frames, OP3.num_joints))
    q = np.clip(q, OP3.lower, OP3.upper)
    base = floating_base(OP3, motion, q)
    held, held_base = ds.hold_double_support(OP3, motion, q, base)
    assert held.shape == q.shape
    assert check_limits(OP3, q, 1.0 / 125.0).ok  # as a solve hands them over
    assert check_limits(OP3, held, 1.0 / 125.0).ok
    assert np.all(held >= OP3.lower)
    assert np.all(held <= OP3.upper)
    legs = np.concatenate([leg.joints for leg in ds.robot_legs(OP3).values()])
    others = np.setdiff1d(np.arange(OP3.num_joints), legs)
    assert np.array_equal(held[:, others], q[:, others])
    assert held_base.root_pos.shape == (motion.num_frames, 3)
    one_foot = dataclasses.replace(
        OP3, bones=tuple(b for b in OP3.bones if not b.canonical.startswith("Right"))
    )
    same, same_base = ds.hold_double_support(one_foot, motion, q, base)
    assert np.array_equal(same, q)
    assert same_base is base
