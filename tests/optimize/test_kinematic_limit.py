"""The kinematic limit: exact on reachable targets, never worse than its candidates."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import SolveError
from robot_retarget.optimize.kinematic_limit import KinematicLimit, SegmentFrames
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics

# OP3's scored segments (the bones' frames; the torso between the limbs' trunk links).
OP3_SEGMENTS: tuple[SegmentFrames, ...] = (
    (("l_sho_roll_link",), ("l_el_link",)),
    (("r_sho_roll_link",), ("r_el_link",)),
    (("l_el_link",), ("l_hand",)),
    (("r_el_link",), ("r_hand",)),
    (("l_hip_center",), ("l_knee_center",)),
    (("r_hip_center",), ("r_knee_center",)),
    (("l_knee_center",), ("l_ankle_center",)),
    (("r_knee_center",), ("r_ankle_center",)),
    (("l_hip_yaw_link", "r_hip_yaw_link"), ("l_sho_pitch_link", "r_sho_pitch_link")),
)
AXES = np.eye(3)  # OP3's root: x forward, y left, z up


@pytest.fixture(scope="module")
def limit(op3: RobotConfig) -> KinematicLimit:
    return KinematicLimit(op3, OP3_SEGMENTS, AXES, random_starts=3, jit=False)


def reference_directions(config: RobotConfig, q: np.ndarray) -> np.ndarray:
    """(T, S, 3) unit segment directions by numpy FK (independent of casadi)."""
    kin = RobotKinematics(config)
    out = []
    for starts, ends in OP3_SEGMENTS:
        a = kin.frame_positions(q, list(starts)).mean(axis=-2)
        b = kin.frame_positions(q, list(ends)).mean(axis=-2)
        out.append(b - a)
    d = np.stack(out, axis=-2)
    return np.asarray(d / np.linalg.norm(d, axis=-1, keepdims=True))


def mean_angle(config: RobotConfig, q: np.ndarray, targets: np.ndarray) -> np.ndarray:
    d = reference_directions(config, q)
    cos = np.clip(np.sum(d * targets, axis=-1), -1.0, 1.0)
    return np.asarray(np.arccos(cos).mean(axis=-1))


def test_groups_split_the_limbs(limit: KinematicLimit) -> None:
    assert sorted(map(sorted, limit.groups)) == [[0, 2], [1, 3], [4, 6], [5, 7], [8]]
    torso = limit.groups.index(next(g for g in limit.groups if g == [8]))
    assert limit.group_joints[torso].size == 0


def test_reachable_targets_are_matched_exactly(op3: RobotConfig, limit: KinematicLimit) -> None:
    q = np.random.default_rng(3).uniform(op3.lower, op3.upper, size=(4, op3.num_joints))
    targets = reference_directions(op3, q)
    result = limit.solve(targets)
    assert np.all(result.q >= op3.lower)
    assert np.all(result.q <= op3.upper)
    assert np.max(result.angles) < 1e-5
    np.testing.assert_allclose(result.angles.mean(axis=1), mean_angle(op3, result.q, targets),
                               atol=1e-7)  # fmt: skip


@settings(max_examples=5)
@given(seed=st.integers(0, 10_000))
def test_never_worse_than_a_candidate(op3: RobotConfig, limit: KinematicLimit, seed: int) -> None:
    rng = np.random.default_rng(seed)
    targets = rng.normal(size=(2, len(OP3_SEGMENTS), 3))
    targets /= np.linalg.norm(targets, axis=-1, keepdims=True)
    cands = rng.uniform(op3.lower, op3.upper, size=(2, 3, op3.num_joints))
    result = limit.solve(targets, cands)
    best = mean_angle(op3, result.q, targets)
    for k in range(cands.shape[1]):
        assert np.all(best <= mean_angle(op3, cands[:, k], targets) + 1e-9)


def test_bent_elbow_out_of_reach_is_the_least_angle(
    op3: RobotConfig, limit: KinematicLimit
) -> None:
    """An elbow bent forward with the upper arm hanging (OP3's arm has no upper-arm twist):
    the limit trades the two arm segments off; its mean is below any single pose we try."""
    q0 = np.zeros((1, op3.num_joints))
    targets = reference_directions(op3, q0)
    targets[0, 0] = (0.0, 0.0, -1.0)  # left upper arm hanging
    targets[0, 2] = (1.0, 0.0, 0.0)  # left forearm forward
    result = limit.solve(targets)
    arm = result.angles[0, [0, 2]].sum()
    assert 0.1 < arm <= np.pi / 2 + 1e-9  # not reachable; never worse than a 90° bend
    rng = np.random.default_rng(0)
    trials = rng.uniform(op3.lower, op3.upper, size=(2000, op3.num_joints))
    d = reference_directions(op3, trials)
    trial_arm = sum(np.arccos(np.clip(d[:, k] @ targets[0, k], -1, 1)) for k in (0, 2))
    assert arm <= trial_arm.min() + 1e-9


def test_bad_inputs(op3: RobotConfig, limit: KinematicLimit) -> None:
    with pytest.raises(SolveError):
        limit.solve(np.zeros((1, 3, 3)))
    with pytest.raises(SolveError):
        limit.solve(np.full((1, len(OP3_SEGMENTS), 3), np.nan))
    with pytest.raises(SolveError):
        limit.solve(np.ones((2, len(OP3_SEGMENTS), 3)), np.zeros((1, 1, op3.num_joints)))
    with pytest.raises(SolveError):
        KinematicLimit(op3, (), AXES, jit=False)
    with pytest.raises(SolveError):
        KinematicLimit(op3, OP3_SEGMENTS, np.eye(2), jit=False)
