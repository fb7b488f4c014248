"""The lead-in's base: upright at the start, into the first frame's pose, feet on the floor."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.optimize.bone_model import body_to_root
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.floating_base import trajectory_feet
from robot_retarget.pipeline.lead_in import lead_in, lead_in_base, upright_rotation
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig


def _tilt(config: RobotConfig, root_quat: np.ndarray) -> float:
    """The angle (rad) between the base's up axis and the world's."""
    up = quat.to_matrix(root_quat) @ body_to_root(config)[:, 2]
    return float(np.arccos(np.clip(up[2], -1.0, 1.0)))


def test_a_lead_in_comes_before_t0_at_the_ramp_speed_and_keeps_the_feet_on_the_floor(
    step: RetargetStep, demo: HumanMotion, op3: RobotConfig
) -> None:
    plain = convert_motion(demo, step, fps=30.0).trajectory
    result = convert_motion(demo, step, fps=30.0, lead_in_speed_fraction=0.25)
    traj = result.trajectory
    k = result.lead_in_frames
    assert k == traj.num_frames - plain.num_frames > 5
    assert traj.t0 == pytest.approx(-k / 30.0)
    np.testing.assert_array_equal(traj.q[k:], plain.q)  # the clip itself is unchanged
    steps = np.abs(np.diff(np.vstack([op3.init_pose, traj.q[: k + 1]]), axis=0))
    assert np.all(steps <= 0.25 * op3.max_velocity / 30.0 + 1e-12)  # at the ramp speed
    assert result.limits.ok  # checked from the init pose
    assert traj.root_pos is not None
    assert traj.root_quat is not None
    assert plain.root_pos is not None
    assert plain.root_quat is not None
    np.testing.assert_array_equal(traj.root_pos[k:], plain.root_pos)  # the clip's base as before
    np.testing.assert_array_equal(traj.root_quat[k:], plain.root_quat)
    feet = trajectory_feet(op3, traj.q, traj.root_pos, traj.root_quat)
    floor_first = feet[k, :, 2].min()
    assert abs(floor_first) < 1e-3  # the demo starts standing
    lowest = feet[:k, :, 2].min(axis=1)
    share = np.arange(1, k + 1) / (k + 1)
    np.testing.assert_allclose(lowest, share * floor_first, atol=1e-9)  # never floating
    # It starts upright (the init pose, one step before the first lead-in frame) and turns at
    # an even pace into the first frame's orientation.
    assert _tilt(op3, traj.root_quat[0]) <= _tilt(op3, traj.root_quat[k]) / (k + 1) + 1e-9
    turns = quat.angle_between(traj.root_quat[: k + 1][1:], traj.root_quat[: k + 1][:-1])
    assert np.ptp(turns[:-1]) < 1e-6 + 1e-3 * turns.max()
    assert turns[-1] <= turns[0] + 1e-6


@settings(max_examples=25, deadline=None)
@given(
    lean=st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
    angle=st.floats(0.0, 0.6),
    heading=st.floats(-np.pi, np.pi),
    height=st.floats(0.0, 0.1),
    joints=st.integers(0, 2**31 - 1),
)
def test_any_first_frame_is_led_into_from_upright_with_its_feet_centred(
    op3: RobotConfig,
    lean: tuple[float, float, float],
    angle: float,
    heading: float,
    height: float,
    joints: int,
) -> None:
    rng = np.random.default_rng(joints)
    q_first = rng.uniform(op3.lower, op3.upper)
    first_quat = quat.mul(
        quat.from_axis_angle([0.0, 0.0, 1.0], heading), quat.from_axis_angle(lean, angle)
    )
    # The first frame's base: its lowest foot point ``height`` above the floor.
    local = trajectory_feet(op3, q_first[None], np.zeros((1, 3)), first_quat[None])[0]
    pos_first = np.array([0.3, -0.2, height - local[:, 2].min()])
    lead = lead_in(op3, q_first, 0.25 * op3.max_velocity / 30.0)
    pos, quats = lead_in_base(op3, lead, q_first, pos_first, first_quat)
    k = len(lead)
    assert pos.shape == (k, 3)
    assert quats.shape == (k, 4)
    if k == 0:
        return
    feet = trajectory_feet(op3, lead, pos, quats)
    share = np.arange(1, k + 1) / (k + 1)
    np.testing.assert_allclose(feet[:, :, 2].min(axis=1), share * height, atol=1e-9)
    first_feet = local + pos_first
    standing = first_feet[:, 2] <= first_feet[:, 2].min() + 0.01
    np.testing.assert_allclose(
        feet[:, standing, :2].mean(axis=1),
        np.broadcast_to(first_feet[standing, :2].mean(axis=0), (k, 2)),
        atol=1e-9,
    )
    # From upright, facing the first frame's heading; the last lead-in frame next to it.
    # (a tilt along the turn's geodesic, not exactly a share of the first frame's tilt)
    assert _tilt(op3, quats[0]) <= 1.05 * _tilt(op3, first_quat) / (k + 1) + 1e-9
    forward = quat.to_matrix(quats[0]) @ body_to_root(op3)[:, 0]
    first_forward = quat.to_matrix(first_quat) @ body_to_root(op3)[:, 0]
    assert float(forward[:2] @ first_forward[:2]) >= 0.0
    assert float(quats[-1] @ first_quat) > 0.0  # the same sign as the clip's
    # An even pace: the last step is a (k + 1)-th of the turn from upright. The turn is not
    # ``angle`` itself: a lean axis with a vertical part also turns the heading the upright
    # start takes (hypothesis found 0.00947 rad against 0.5625 / 60 · 1.01).
    upright = quat.from_matrix(upright_rotation(op3, quat.to_matrix(first_quat)))
    turn = float(quat.angle_between(upright, first_quat))
    assert quat.angle_between(quats[-1], first_quat) <= turn / (k + 1) * (1 + 1e-6) + 1e-9
