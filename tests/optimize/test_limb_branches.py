"""Retargeter.settle starts every limb in its best branch (LimbBranches)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.optimize import FrameTargets, Retargeter
from robot_retarget.optimize.chains import coupled_groups
from robot_retarget.optimize.limb_branches import LimbBranches
from robot_retarget.robot.config import RobotConfig

_STATIC_DT_S = 1e3  # as settle: no velocity limit, no smoothing


def _plain_settle(r: Retargeter, targets: FrameTargets, start: np.ndarray) -> float:
    """What settle did before the multi-start: repeated solves from ``start``."""
    r.reset(start)
    cost = np.inf
    for _ in range(10):
        cost = r.solve(targets, _STATIC_DT_S).cost
    return float(cost)


def test_op3_limbs_are_arms_and_legs(op3: RobotConfig) -> None:
    segments = [((b.start_frame,), (b.end_frame,)) for b in op3.bones]
    groups, joints = coupled_groups(op3, segments)
    names = [b.canonical for b in op3.bones]
    limbs = sorted(sorted(names[i] for i in g) for g in groups if len(g) >= 2)
    assert limbs == [
        ["LeftArm", "LeftForeArm"],
        ["LeftFoot", "LeftLeg", "LeftUpLeg"],
        ["RightArm", "RightForeArm"],
        ["RightFoot", "RightLeg", "RightUpLeg"],
    ]
    arm = next(j for g, j in zip(groups, joints, strict=True) if names[g[0]] == "LeftArm")
    assert [op3.joints[i].name for i in arm] == ["l_sho_pitch", "l_sho_roll", "l_el"]


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_settle_is_never_worse_than_settling_from_the_start(
    op3_retargeter: Retargeter, seed: int
) -> None:
    r = op3_retargeter
    cfg = r.config
    rng = np.random.default_rng(seed)
    goal = rng.uniform(cfg.lower, cfg.upper)
    targets = FrameTargets(r.bone_directions(goal), r.bone_normals(goal))
    start = rng.uniform(cfg.lower, cfg.upper)
    plain = _plain_settle(r, targets, start)
    r.reset(start)
    settled = r.settle(targets)
    # The same optimum reached from two starts: the SQP stops at dual infeasibility 1e-7, so
    # the costs may differ by ~1e-7 (7.3e-8 at seed 144; ≤ 1e-10 over 299 other seeds).
    assert settled.cost <= plain + 1e-6
    assert np.all(settled.q >= cfg.lower)
    assert np.all(settled.q <= cfg.upper)
    # The next solve goes on from the settled pose at the velocity limits.
    np.testing.assert_array_equal(r.q_prev, settled.q)


def test_settle_finds_the_other_elbow_branch(op3_retargeter: Retargeter) -> None:
    # Both arms bent "backwards" (OP3's elbows bend both ways), started from the init pose,
    # whose elbows bend the human way: settling from there alone stays in the wrong branch.
    r = op3_retargeter
    cfg = r.config
    names = [j.name for j in cfg.joints]
    goal = cfg.init_pose.copy()
    for joint, value in (
        ("l_sho_pitch", 0.6),
        ("l_sho_roll", 0.2),
        ("l_el", 1.2),
        ("r_sho_pitch", -0.6),
        ("r_sho_roll", -0.2),
        ("r_el", -1.2),
    ):
        goal[names.index(joint)] = value  # fmt: skip
    targets = FrameTargets(r.bone_directions(goal))
    plain = _plain_settle(r, targets, cfg.init_pose)
    r.reset()
    settled = r.settle(targets)
    assert settled.cost < 0.1 * plain  # what is left: the weak pull toward the init pose
    arms = [names.index(n) for n in ("l_sho_pitch", "l_sho_roll", "l_el", "r_el")]
    np.testing.assert_allclose(settled.q[arms], goal[arms], atol=1e-3)


def test_poppy_limbs_hang_from_its_spine(poppy: RobotConfig) -> None:
    """The spine moves every bone above the hips, so grouping by shared joints alone made one
    15-joint group of both arms, the head and the spine; the multi-start's limbs leave the
    spine out: each arm and each leg on its own joints."""
    r = Retargeter(poppy)
    names = sorted(sorted(poppy.joints[i].name for i in limb) for limb in r.limbs)
    arms = [sorted(f"{s}_{j}" for j in ("shoulder_y", "shoulder_x", "arm_z", "elbow_y"))
            for s in ("l", "r")]  # fmt: skip
    legs = [sorted(f"{s}_{j}" for j in ("hip_x", "hip_z", "hip_y", "knee_y", "ankle_y"))
            for s in ("l", "r")]  # fmt: skip
    assert names == sorted(arms + legs)


def test_the_start_count_a_whole_clip_choice_indexes_is_the_starts_given() -> None:
    q = np.array([0.4, -0.2, 0.7])
    starts = LimbBranches.starts(q, np.array([0, 2]))
    assert len(starts) == LimbBranches.NUM_STARTS
    np.testing.assert_array_equal(starts[0], q)  # the current optimum first
