"""Acceptance tests of the Retargeter: hard limits, recovery, twist bound, safe failure."""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import SolveError
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.optimize import (
    ClipTargets,
    FrameTargets,
    Retargeter,
    SolveResult,
    SolveStatus,
    targets_from_globals,
)
from robot_retarget.robot.config import RobotConfig

TwistArmFactory = Callable[[dict[str, float]], RobotConfig]

_EXACT = 1e-12  # rad: the only slack allowed on a hard limit


def _angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def _random_units(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    v = rng.normal(size=(n, 3)) * scale
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# --------------------------------------------------------------------------- hard limits
@settings(max_examples=40)
@given(
    seed=st.integers(0, 2**32 - 1),
    dt_s=st.floats(1e-3, 0.2),
    unreachable=st.booleans(),
)
def test_every_output_inside_limits_and_velocity_box(
    op3_retargeter: Retargeter, seed: int, dt_s: float, unreachable: bool
) -> None:
    r = op3_retargeter
    cfg = r.config
    rng = np.random.default_rng(seed)
    q_prev = rng.uniform(cfg.lower, cfg.upper)
    r.reset(q_prev)
    nb = len(r.bone_names)
    for _ in range(3):
        if unreachable:  # any directions at all, normals opposite to them, far end effectors
            dirs = _random_units(rng, nb, 1.0)
            targets = FrameTargets(
                dirs,
                -dirs,
                ee_positions=rng.normal(size=(len(r.end_effector_names), 3)) * 10.0,
                root_height_m=float(rng.uniform(-1.0, 0.0)),
            )
        else:
            q = rng.uniform(cfg.lower, cfg.upper)
            targets = FrameTargets(r.bone_directions(q), r.bone_normals(q))
        res = r.solve(targets, dt_s)
        step = cfg.max_velocity * dt_s
        assert np.all(res.q >= cfg.lower - _EXACT)
        assert np.all(res.q <= cfg.upper + _EXACT)
        assert np.all(np.abs(res.q - q_prev) <= step + _EXACT)
        q_prev = res.q


@settings(max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), dt_s=st.floats(1e-3, 0.2))
def test_twist_bound_and_limits_hold_for_unreachable_targets(
    twist_retargeter: Retargeter, seed: int, dt_s: float
) -> None:
    r = twist_retargeter
    cfg = r.config
    rng = np.random.default_rng(seed)
    q_prev = rng.uniform(cfg.lower, cfg.upper) * 0.3  # twists inside the bound to start with
    r.reset(q_prev)
    nb = len(r.bone_names)
    for _ in range(3):
        res = r.solve(FrameTargets(_random_units(rng, nb, 1.0), _random_units(rng, nb, 1.0)), dt_s)
        assert np.all(res.q >= cfg.lower - _EXACT)
        assert np.all(res.q <= cfg.upper + _EXACT)
        assert np.all(np.abs(res.q - q_prev) <= cfg.max_velocity * dt_s + _EXACT)
        if not res.used_fallback:
            assert np.all(np.abs(r.bone_twists(res.q)) <= math.radians(100.0) + 1e-6)
        q_prev = res.q


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_targets_raise_and_produce_no_command(
    op3_retargeter: Retargeter, bad: float
) -> None:
    r = op3_retargeter
    r.reset()
    before = r.q_prev
    dirs = r.bone_directions(r.config.init_pose)
    dirs[3, 1] = bad
    with pytest.raises(SolveError, match="NaN or infinite"):
        r.solve(FrameTargets(dirs), 0.01)
    normals = r.bone_normals(r.config.init_pose)
    normals[0, 0] = bad
    with pytest.raises(SolveError, match="NaN or infinite"):
        r.solve(FrameTargets(r.bone_directions(r.config.init_pose), normals), 0.01)
    np.testing.assert_array_equal(r.q_prev, before)


@pytest.mark.parametrize("dt_s", [0.0, -0.01, math.nan, math.inf])
def test_bad_dt_raises(op3_retargeter: Retargeter, dt_s: float) -> None:
    dirs = op3_retargeter.bone_directions(op3_retargeter.config.init_pose)
    with pytest.raises(SolveError, match="dt_s"):
        op3_retargeter.solve(FrameTargets(dirs), dt_s)


def test_wrong_target_shape_raises(op3_retargeter: Retargeter) -> None:
    with pytest.raises(SolveError, match="shape"):
        op3_retargeter.solve(FrameTargets(np.ones((3, 3))), 0.01)


# --------------------------------------------------------------------------- recovery
def test_recovers_fk_targets_of_random_feasible_angles(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    cfg = r.config
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(40):
        q = rng.uniform(cfg.lower, cfg.upper)
        targets = FrameTargets(r.bone_directions(q), r.bone_normals(q))
        r.reset()
        res = r.solve(targets, 10.0)  # dt large: the velocity box does not bind
        errors.append(_angles_deg(r.bone_directions(res.q), targets.directions))
    assert float(np.median(errors)) < 0.5


def test_tracks_a_smooth_feasible_trajectory(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    cfg = r.config
    t = np.linspace(0.0, 2.0, 200)[:, None]
    mid = 0.5 * (cfg.lower + cfg.upper)
    half = 0.4 * (cfg.upper - cfg.lower)
    traj = mid + half * np.sin(2.0 * np.pi * 0.5 * t + np.arange(cfg.num_joints))
    r.reset(traj[0])
    errors = []
    for q in traj[1:]:
        res = r.solve(FrameTargets(r.bone_directions(q), r.bone_normals(q)), 0.01)
        assert res.status is SolveStatus.OPTIMAL
        errors.append(_angles_deg(r.bone_directions(res.q), r.bone_directions(q)))
    assert float(np.median(errors)) < 0.5


# --------------------------------------------------------------------------- twist bound
def test_forearm_twisted_150_deg_comes_back_within_alpha(twist_retargeter: Retargeter) -> None:
    r = twist_retargeter
    cfg = r.config
    q = np.zeros(cfg.num_joints)
    q[cfg.joint_index("l_el")] = -0.5
    q[cfg.joint_index("l_fore_roll")] = math.radians(150.0)
    fore = r.bone_names.index("LeftForeArm")
    assert math.degrees(r.bone_twists(q)[fore]) == pytest.approx(150.0, abs=1e-6)
    targets = FrameTargets(r.bone_directions(q), r.bone_normals(q))
    r.reset()
    for _ in range(10):
        res = r.solve(targets, 0.1)
    alpha = r.settings.twist_limit_rad("LeftForeArm")
    twists = r.bone_twists(res.q)
    assert np.all(np.abs(twists) <= alpha + 1e-6)
    # It twists as far as allowed, towards the target.
    assert twists[fore] == pytest.approx(alpha, abs=math.radians(1.0))
    assert res.status is SolveStatus.OPTIMAL


def test_per_bone_twist_override(twist_arm_factory: TwistArmFactory) -> None:
    # A roll weight well above the init pull (1e-4), so the unbounded forearm reaches its roll.
    cfg = twist_arm_factory({"twist_limit_deg.LeftForeArm": 30.0, "w_orientation": 0.1})
    r = Retargeter(cfg, jit=False)
    q = np.zeros(cfg.num_joints)
    q[cfg.joint_index("l_fore_roll")] = math.radians(90.0)
    q[cfg.joint_index("r_fore_roll")] = math.radians(90.0)
    targets = FrameTargets(r.bone_directions(q), r.bone_normals(q))
    for _ in range(10):
        res = r.solve(targets, 0.1)
    twists = np.degrees(r.bone_twists(res.q))
    assert twists[r.bone_names.index("LeftForeArm")] == pytest.approx(30.0, abs=1.0)
    assert twists[r.bone_names.index("RightForeArm")] == pytest.approx(90.0, abs=1.0)


# --------------------------------------------------------------------------- safe failure
def test_start_outside_limits_moves_inside_at_max_velocity(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    cfg = r.config
    dt = 0.01
    step = cfg.max_velocity * dt
    start = cfg.init_pose.copy()
    start[0] = cfg.upper[0] + 0.3  # above the upper limit
    start[5] = cfg.lower[5] - 0.2  # below the lower limit
    r.reset(start)
    targets = FrameTargets(r.bone_directions(cfg.init_pose), r.bone_normals(cfg.init_pose))
    prev = start
    for _ in range(200):
        q = r.solve(targets, dt).q
        assert np.all(np.abs(q - prev) <= step + _EXACT)
        # Never further outside than before, and closer by a full step while outside.
        for i in (0, 5):
            out_before = max(prev[i] - cfg.upper[i], cfg.lower[i] - prev[i], 0.0)
            out_now = max(q[i] - cfg.upper[i], cfg.lower[i] - q[i], 0.0)
            assert out_now <= max(out_before - step[i], 0.0) + _EXACT
        prev = q
    assert np.all(prev >= cfg.lower)
    assert np.all(prev <= cfg.upper)


def test_infeasible_twist_bound_falls_back_to_projection(op3: RobotConfig) -> None:
    # α = 0 on every bone: the init pose's upper-arm twist (≈ 15°) cannot reach 0 in one
    # 1 ms step, so the solve fails and the projection is used.
    cfg = dataclasses.replace(op3, retarget={"twist_limit_deg": 0.0})
    r = Retargeter(cfg, jit=False)
    dt = 1e-3
    targets = FrameTargets(r.bone_directions(cfg.init_pose))
    res = r.solve(targets, dt)
    assert res.status is SolveStatus.FALLBACK
    assert res.used_fallback
    assert res.max_violation > 0.0
    assert np.all(np.abs(res.q - cfg.init_pose) <= cfg.max_velocity * dt + _EXACT)
    assert np.all(res.q >= cfg.lower)
    assert np.all(res.q <= cfg.upper)
    assert math.isfinite(res.cost)


def test_result_reports_solver_facts(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    r.reset()
    q = r.config.init_pose + 0.05
    res = r.solve(FrameTargets(r.bone_directions(q), r.bone_normals(q)), 0.02)
    assert res.ok
    assert not res.used_fallback
    assert res.iterations is None  # a converged live frame leaves casadi's statistics unread
    count, status = r.online_solver.last_status()
    assert count >= 1
    assert status == "Solve_Succeeded"
    assert res.solve_time_s > 0.0  # measured (speed itself: bench solve)
    assert res.max_violation <= 1e-6
    assert res.cost >= 0.0
    assert res.q.shape == (r.num_joints,)


def test_a_frame_stopped_at_max_iter_reports_its_count_and_status(
    twist_arm_factory: TwistArmFactory,
) -> None:
    """One SQP iteration toward a far pose: MAX_ITER with casadi's count and status, read
    because the frame did not end optimal (a converged frame leaves them unread)."""
    cfg = twist_arm_factory({"max_iter": 1})
    r = Retargeter(cfg, jit=False)
    q = np.clip(np.full(cfg.num_joints, 1.0), cfg.lower, cfg.upper)
    res = r.solve(FrameTargets(r.bone_directions(q), r.bone_normals(q)), 1.0)
    assert res.status is SolveStatus.MAX_ITER
    assert res.iterations == 1
    assert res.message == "Maximum_Iterations_Exceeded"
    assert np.all(res.q >= cfg.lower)
    assert np.all(res.q <= cfg.upper)


def test_step_tolerance_is_a_share_of_the_finest_servo_tick(op3_retargeter: Retargeter) -> None:
    # Every OP3 servo has 4096 ticks per turn; the default stops at a third of one.
    assert op3_retargeter.settings.step_tol_ticks == pytest.approx(0.33)
    assert op3_retargeter.step_tol_rad == pytest.approx(0.33 * 2 * math.pi / 4096)


def test_frames_stopped_at_the_step_tolerance_stay_within_a_tick(poppy: RobotConfig) -> None:
    """Poppy following the demo at its velocity limits: where the SQP's steps shrink slowly,
    the step tolerance ends the solve (STEP_TOL, counted as converged), and every command stays
    within one servo tick of the same sequence solved to the KKT tolerances."""
    stopped = Retargeter(poppy, jit=False)
    full = Retargeter(dataclasses.replace(poppy, retarget={"step_tol_ticks": 0}), jit=False)
    assert full.step_tol_rad == 0.0
    rate = poppy.control_rate_hz
    motion = demo_motion(fps=rate)
    targets = targets_from_globals(stopped.problem, motion.positions(), motion.global_quats())
    statuses = []
    gap = 0.0
    for t in range(motion.num_frames):
        a = stopped.solve(targets.frame(t), 1.0 / rate)
        b = full.solve(targets.frame(t), 1.0 / rate)
        assert b.status is not SolveStatus.STEP_TOL
        if a.status is SolveStatus.STEP_TOL:
            assert a.ok
            assert a.message == "Search_Direction_Becomes_Too_Small"
            assert a.iterations is not None
            assert a.iterations < stopped.settings.max_iter
        statuses.append(a.status)
        gap = max(gap, float(np.abs(a.q - b.q).max()))
    assert statuses.count(SolveStatus.STEP_TOL) >= 0.05 * motion.num_frames
    assert gap < 2 * math.pi / 4096


# --------------------------------------------------------------------------- JIT and cache
def test_no_compiler_falls_back_to_interpreted_solver(
    twist_arm: RobotConfig, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING):
        r = Retargeter(twist_arm, cache_dir=tmp_path, compiler="no-such-cc-for-robot-retarget")
    assert not r.jit_used
    assert "no C compiler" in caplog.text
    assert not list(tmp_path.iterdir())
    q = np.full(twist_arm.num_joints, 0.2)
    res = r.solve(FrameTargets(r.bone_directions(q), r.bone_normals(q)), 1.0)
    assert res.ok
    assert float(np.max(_angles_deg(r.bone_directions(res.q), r.bone_directions(q)))) < 0.5


def test_compiled_solver_is_cached_on_disk(twist_arm: RobotConfig, cache_dir: Path) -> None:
    first = Retargeter(twist_arm, cache_dir=cache_dir)
    files = sorted(p.name for p in cache_dir.iterdir())
    assert any(name.endswith(".casadi") for name in files)
    second = Retargeter(twist_arm, cache_dir=cache_dir, compiler="no-such-cc-for-robot-retarget")
    assert first.jit_used
    assert second.jit_used
    assert sorted(p.name for p in cache_dir.iterdir()) == files
    q = np.full(twist_arm.num_joints, -0.1)
    targets = FrameTargets(first.bone_directions(q), first.bone_normals(q))
    np.testing.assert_allclose(first.solve(targets, 1.0).q, second.solve(targets, 1.0).q)


# --------------------------------------------------------------------------- offline
@settings(max_examples=5)
@given(
    frames=st.integers(1, 40),
    seed=st.integers(0, 2**32 - 1),
)
def test_offline_clip_respects_limits_for_any_length(
    op3_retargeter: Retargeter, frames: int, seed: int
) -> None:
    r = op3_retargeter
    cfg = r.config
    rng = np.random.default_rng(seed)
    nb = len(r.bone_names)
    dirs = np.stack([_random_units(rng, nb, 1.0) for _ in range(frames)])
    dt = 1.0 / 120.0
    start = rng.uniform(cfg.lower, cfg.upper)
    res, timing = r.solve_clip(ClipTargets(dirs), dt, q_start=start)
    assert res.q.shape == (frames, cfg.num_joints)
    assert sum(timing.window_frames) == frames
    prev = start
    for q in res.q:
        assert np.all(q >= cfg.lower - _EXACT)
        assert np.all(q <= cfg.upper + _EXACT)
        assert np.all(np.abs(q - prev) <= cfg.max_velocity * dt + _EXACT)
        prev = q


def test_offline_recovers_a_smooth_trajectory_and_keeps_online_state(
    op3_retargeter: Retargeter,
) -> None:
    r = op3_retargeter
    cfg = r.config
    t = np.linspace(0.0, 1.0, 60)[:, None]
    traj = cfg.init_pose + 0.3 * np.sin(2.0 * np.pi * t + np.arange(cfg.num_joints))
    traj = np.clip(traj, cfg.lower, cfg.upper)
    dirs = np.stack([r.bone_directions(q) for q in traj])
    normals = np.stack([r.bone_normals(q) for q in traj])
    r.reset()
    before = r.q_prev
    res, _ = r.solve_clip(ClipTargets(dirs, normals), 1.0 / 60.0, q_start=traj[0])
    np.testing.assert_array_equal(r.q_prev, before)
    err = _angles_deg(np.stack([r.bone_directions(q) for q in res.q]), dirs)
    assert float(np.median(err)) < 0.5
    assert not res.used_fallback


def test_offline_rejects_non_finite_targets_before_solving(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    dirs = np.stack([r.bone_directions(r.config.init_pose)] * 5)
    dirs[4, 0, 0] = math.nan
    with pytest.raises(SolveError, match="NaN"):
        r.solve_clip(ClipTargets(dirs), 0.01)
    with pytest.raises(SolveError, match="no frames"):
        r.solve_clip(ClipTargets(dirs[:0]), 0.01)


# --------------------------------------------------------------------------- optional terms
def test_feet_stay_above_the_ground_when_the_root_height_is_known(
    op3_retargeter: Retargeter,
) -> None:
    r = op3_retargeter
    cfg = r.config
    straight = np.zeros(cfg.num_joints)  # legs straight: the toes 0.26 m below the root
    targets = FrameTargets(r.bone_directions(straight), root_height_m=0.2)
    r.reset()
    for _ in range(100):
        res = r.solve(targets, 0.02)
    heights = np.asarray(r.problem.feet_function(res.q)).ravel()
    assert np.all(heights >= -0.2 - 1e-6)
    assert float(np.min(heights)) == pytest.approx(-0.2, abs=1e-3)  # as low as allowed
    free = r.solve(FrameTargets(targets.directions), 0.02)  # height unknown: no constraint
    for _ in range(100):
        free = r.solve(FrameTargets(targets.directions), 0.02)
    assert float(np.min(np.asarray(r.problem.feet_function(free.q)))) < -0.21


def test_end_effector_targets_are_tracked(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    cfg = r.config
    rng = np.random.default_rng(11)
    q = np.clip(cfg.init_pose + rng.normal(scale=0.3, size=cfg.num_joints), cfg.lower, cfg.upper)
    ee = r.end_effector_positions(q)
    wrong_dirs = r.bone_directions(cfg.init_pose)  # directions disagree; positions decide
    targets = FrameTargets(wrong_dirs, ee_positions=ee, ee_weights=np.full(len(ee), 50.0))
    r.reset()
    for _ in range(50):
        res = r.solve(targets, 0.05)
    err = np.linalg.norm(r.end_effector_positions(res.q) - ee, axis=1)
    assert float(np.median(err)) < 0.01


def test_poppy_recovers_poses_around_its_init_pose(poppy: RobotConfig) -> None:
    # Poppy's 5-joint spine makes far-away poses need many SQP iterations (and admit local
    # minima) from the init pose: here, poses within ≈ 17° per joint of it, a few online steps.
    r = Retargeter(poppy, jit=False)
    rng = np.random.default_rng(2)
    errors = []
    for _ in range(10):
        noise = rng.normal(scale=0.3, size=poppy.num_joints)
        q = np.clip(poppy.init_pose + noise, poppy.lower, poppy.upper)
        targets = FrameTargets(r.bone_directions(q), r.bone_normals(q))
        r.reset()
        for _ in range(3):
            res = r.solve(targets, 10.0)
            assert np.all(res.q >= poppy.lower)
            assert np.all(res.q <= poppy.upper)
        errors.append(_angles_deg(r.bone_directions(res.q), targets.directions))
    assert float(np.median(errors)) < 0.5


@pytest.mark.data
def test_offline_windows_are_smoother_than_online_on_mocap(
    shared_data_dir: Path, op3_retargeter: Retargeter
) -> None:
    from robot_retarget.motion import load_motion
    from robot_retarget.optimize import targets_from_rotations

    r = op3_retargeter
    motion = load_motion(shared_data_dir / "mocap" / "05" / "05_02.bvh", max_frames=240)
    targets = targets_from_rotations(
        r.problem, motion.skeleton, motion.local_quats, root_pos=motion.root_pos
    )
    dt = 1.0 / motion.fps
    r.reset()
    online = np.stack([r.solve(targets.frame(t), dt).q for t in range(len(targets))])
    offline, _ = r.solve_clip(targets, dt)

    def rms_acc(q: np.ndarray) -> float:
        return float(np.sqrt(np.mean((np.diff(q, 2, axis=0) / dt**2) ** 2)))

    def mean_err(q: np.ndarray) -> float:
        dirs = np.stack([r.bone_directions(x) for x in q])
        return float(np.mean(_angles_deg(dirs, targets.directions)))

    assert rms_acc(offline.q) < 0.95 * rms_acc(online)
    assert mean_err(offline.q) <= mean_err(online) + 0.1
    assert not offline.used_fallback


def test_settle_keeps_the_lower_cost_start_that_kept_its_constraints(
    twist_retargeter: Retargeter, monkeypatch: pytest.MonkeyPatch
) -> None:
    """settle ranks its three starts by (fell back, cost) and commits the winner as the
    history and the next solve's start."""
    r = twist_retargeter
    n = r.num_joints

    def fake(q: float, cost: float, fell_back: bool) -> SolveResult:
        status = SolveStatus.FALLBACK if fell_back else SolveStatus.OPTIMAL
        return SolveResult(status, np.full(n, q), cost, None, 0.0, 0.0, fell_back)

    targets = FrameTargets(
        r.bone_directions(r.config.init_pose), r.bone_normals(r.config.init_pose)
    )
    for three, expected in (
        ((fake(0.1, 0.5, False), fake(0.2, 0.3, False), fake(0.3, 0.4, False)), 0.2),
        ((fake(0.1, 0.2, False), fake(0.2, 0.3, False), fake(0.3, 0.4, False)), 0.1),
        ((fake(0.1, 0.5, False), fake(0.2, 0.3, False), fake(0.3, 0.1, False)), 0.3),
        # a fallback loses to any pose
        ((fake(0.1, 0.01, True), fake(0.2, 0.3, False), fake(0.3, 0.001, True)), 0.2),
    ):
        starts = iter(three)
        monkeypatch.setattr(r, "_settle_from", lambda *_, s=starts: next(s))
        r.reset()
        res = r.settle(targets)
        assert res.q[0] == expected
        q_prev, q_prev2 = r.history()
        np.testing.assert_array_equal(q_prev, res.q)
        np.testing.assert_array_equal(q_prev2, res.q)
        np.testing.assert_array_equal(r.online_solver.x0, res.q)
    monkeypatch.undo()
    r.reset()


@pytest.mark.data
def test_first_frames_settle_inside_their_constraints(
    shared_data_dir: Path, poppy: RobotConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Poppy's first frame of every clip of CMU 02 and 07 through the shipped network, settled
    as convert starts: never a fallback, and the lowest-cost of the three starts. Re-solving
    without a velocity limit from an extrapolated start threw 02_08, 02_10, 07_06 and 07_12
    into twisted poses that broke their twist bounds; on 02_08 the pursuit's optimum costs a
    sixteenth of the unbounded re-solves' (0.04 against 0.67). Elsewhere that extrapolated
    start finds the best optimum of the three."""
    from robot_retarget.motion import load_motion
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.pipeline.step import RetargetStep

    candidates: list[SolveResult] = []
    settle_from = Retargeter._settle_from

    def recorded(self: Retargeter, *args: object) -> SolveResult:
        result = settle_from(self, *args)  # type: ignore[arg-type]
        candidates.append(result)
        return result

    monkeypatch.setattr(Retargeter, "_settle_from", recorded)
    r = Retargeter(poppy, jit=False)
    step: RetargetStep | None = None
    clips = sorted((shared_data_dir / "mocap").glob("0[27]/*.bvh"))
    assert len(clips) >= 10
    largest_gap = warm_gain = 0.0
    for path in clips:
        motion = load_motion(path, max_frames=1)
        if step is None:
            step = RetargetStep(poppy, default_model_name(), motion.skeleton, retargeter=r)
        step.set_source(motion.skeleton)
        step.reset(poppy.init_pose)
        candidates.clear()
        out = step(motion.local_quats[0], motion.root_pos[0], 0.02, settle=True)
        assert not out.solve.used_fallback, path.name
        assert np.all(out.q >= poppy.lower)
        assert np.all(out.q <= poppy.upper)
        assert len(candidates) == 3
        assert out.solve.cost == min(c.cost for c in candidates if not c.used_fallback)
        largest_gap = max(largest_gap, abs(candidates[0].cost - candidates[1].cost))
        kept = [c.cost for c in candidates[:2] if not c.used_fallback]
        if not candidates[2].used_fallback:
            warm_gain = max(warm_gain, min(kept) - candidates[2].cost)
    assert largest_gap > 0.1  # the first two starts reach different optima, and it matters
    assert warm_gain > 0.01  # so does the third: on 02_02 it is the best, 0.049 against 0.074


def test_warm_up_keeps_the_state_and_q_prev_overrides_it(op3_retargeter: Retargeter) -> None:
    r = op3_retargeter
    cfg = r.config
    start = np.clip(cfg.init_pose + 0.1, cfg.lower, cfg.upper)
    r.reset(start)
    r.warm_up(frames=3)
    np.testing.assert_array_equal(r.q_prev, start)
    measured = np.clip(cfg.init_pose - 0.2, cfg.lower, cfg.upper)
    dt = 0.005
    res = r.solve(FrameTargets(r.bone_directions(cfg.init_pose)), dt, q_prev=measured)
    assert np.all(np.abs(res.q - measured) <= cfg.max_velocity * dt + _EXACT)
    np.testing.assert_array_equal(r.q_prev, res.q)


def test_a_failed_solve_holds_the_previous_command_and_says_so(
    twist_arm_factory: TwistArmFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A solve that stops with any status but the iteration cap or the step tolerance (a NaN
    derivative, "Non_Regular_Sensitivities") failed: whatever its iterate, the frame holds the
    previous command and counts as a fallback (it had passed as MAX_ITER, its iterate taken)."""
    cfg = twist_arm_factory({"max_iter": 1})
    r = Retargeter(cfg, jit=False)
    previous = r.history()[0].copy()
    q = np.clip(np.full(cfg.num_joints, 1.0), cfg.lower, cfg.upper)
    targets = FrameTargets(r.bone_directions(q), r.bone_normals(q))
    monkeypatch.setattr(r.online_solver, "last_status", lambda: (2, "Non_Regular_Sensitivities"))
    res = r.solve(targets, 1.0)
    assert res.status is SolveStatus.FALLBACK
    assert res.used_fallback
    np.testing.assert_array_equal(res.q, previous)
    np.testing.assert_array_equal(r.history()[0], previous)
    monkeypatch.setattr(r.online_solver, "last_status", lambda: (1, "Maximum_Iterations_Exceeded"))
    assert r.solve(targets, 1.0).status is SolveStatus.MAX_ITER
