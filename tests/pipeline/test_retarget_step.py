from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.nn.inference import OnlineRetargeter, load_model
from robot_retarget.optimize import Retargeter, targets_from_rotations
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.copy import FastCopyRetargeter


def test_step_output_is_inside_the_limits(step: RetargetStep, demo: HumanMotion) -> None:
    dt = 1 / 30
    prev = step.config.init_pose
    for t in range(20):
        out = step(demo.local_quats[t], demo.root_pos[t], dt)
        assert out.q.shape == (step.config.num_joints,)
        assert np.all(out.q >= step.config.lower)
        assert np.all(out.q <= step.config.upper)
        assert np.all(np.abs(out.q - prev) <= step.config.max_velocity * dt + 1e-12)
        np.testing.assert_allclose(np.linalg.norm(out.root_quat), 1.0, atol=1e-9)
        assert not out.solve.used_fallback
        assert all(t_s >= 0 for t_s in out.times_s)
        prev = out.q
    assert step.stats.frames == 20


@settings(
    max_examples=15,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    arrays(np.float64, (5, 22, 3), elements=st.floats(-3.0, 3.0)),
    st.floats(0.002, 0.05),
)
def test_no_command_ever_leaves_the_limits(
    step: RetargetStep, op3: RobotConfig, rotvecs: np.ndarray, dt: float
) -> None:
    """Arbitrary (even wild) human poses: every command stays in the position/velocity box."""
    step.reset()
    prev = op3.init_pose
    for frame in quat.from_rotation_vector(rotvecs):
        out = step(frame, np.zeros(3), dt)
        assert np.all(out.q >= op3.lower)
        assert np.all(out.q <= op3.upper)
        assert np.all(np.abs(out.q - prev) <= op3.max_velocity * dt * (1 + 1e-9) + 1e-12)
        prev = out.q


def test_q_prev_override_moves_the_velocity_box(step: RetargetStep, demo: HumanMotion) -> None:
    start = step.config.safe_pose
    out = step(demo.local_quats[0], demo.root_pos[0], 0.01, q_prev=start)
    assert np.all(np.abs(out.q - start) <= step.config.max_velocity * 0.01 + 1e-12)


def test_set_source_restarts_the_network(step: RetargetStep, demo: HumanMotion) -> None:
    a = step(demo.local_quats[5], demo.root_pos[5], 0.01)
    step.set_source(demo.skeleton.scaled(0.5))
    step.reset()
    b = step(demo.local_quats[5], demo.root_pos[5], 0.01)
    assert np.all(np.isfinite(b.q))
    assert a.q.shape == b.q.shape


@pytest.mark.parametrize("name", ["copy", "copy-scaled"])
def test_fast_paths_give_the_reference_commands(
    name: str, op3: RobotConfig, retargeter: Retargeter, demo: HumanMotion
) -> None:
    """numpy copy + per-frame targets = torch OnlineRetargeter + targets_from_rotations."""
    model = load_model(name)
    step = RetargetStep(op3, model, demo.skeleton, retargeter=retargeter)
    assert isinstance(step.online, FastCopyRetargeter)
    online = OnlineRetargeter(model, demo.skeleton.offsets, step.robot_skeleton.offsets)
    dt = 1 / 30
    retargeter.reset()
    want = []
    for t in range(30):
        quats, root = online.step(demo.local_quats[t], demo.root_pos[t])
        targets = targets_from_rotations(
            retargeter.problem,
            step.robot_skeleton,
            quats[None],
            root_pos=root[None],
            level_feet=retargeter.settings.level_feet,
        ).frame(0)
        want.append((retargeter.solve(targets, dt).q, root, quats[0]))
    step.reset()
    for t in range(30):
        out = step(demo.local_quats[t], demo.root_pos[t], dt)
        np.testing.assert_allclose(out.q, want[t][0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(out.root_pos, want[t][1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(out.root_quat, want[t][2], rtol=0, atol=1e-12)


def test_a_frame_that_is_no_pose_is_refused_and_leaves_the_step_as_it_was() -> None:
    """A NaN reached the network's history: every later good frame failed until reset(), and
    a NaN root_pos came out as the frame's root (and stayed in the next ones)."""
    from robot_retarget.errors import InvalidMotionError
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.skeleton.canonical import default_canonical_skeleton

    config = load_robot_config("op3")
    rest = np.zeros((22, 4))
    rest[:, 0] = 1.0
    root = np.array([0.0, 0.9, 0.0])
    steps = [RetargetStep(config, "default", default_canonical_skeleton()) for _ in range(2)]
    for step in steps:
        step(rest, root, 0.008, settle=True)
    bad_quats = rest.copy()
    bad_quats[3, 1] = np.nan
    for quats, pos, what in ((bad_quats, root, "local_quats"),
                             (rest, np.array([np.nan, 0.9, 0.0]), "root_pos")):  # fmt: skip
        with pytest.raises(InvalidMotionError, match=f"{what} holds NaN"):
            steps[0](quats, pos, 0.008)
    with pytest.raises(InvalidMotionError, match=r"\(joints, 4\)"):
        steps[0](rest[:, :3], root, 0.008)
    # A zero quaternion had gone on to a NaN deep in the solve, one of norm 3 as it was.
    for scale in (0.0, 3.0, 1e-12):
        bad = rest.copy()
        bad[8] *= scale
        with pytest.raises(InvalidMotionError, match="row 8 has norm"):
            steps[0](bad, root, 0.008)
    # the refused frames changed nothing: the step goes on as one that never saw them
    a, b = steps[0](rest, root, 0.008), steps[1](rest, root, 0.008)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.root_pos, b.root_pos)


def test_a_root_that_jumps_faster_than_any_performer_is_taken_out_of_the_root_track(
    demo: HumanMotion,
) -> None:
    """A tracker's glitch (50 m away for one frame, and back; or a jump that stays): the
    network integrates root velocities, so the reported root had kept an offset after the
    glitch. Now the root track it sees has no jump: it stands still for the frame of the jump
    (a frame's motion lost, under 3 mm here) and goes on as the clean run's, whether the
    glitch comes back or stays."""
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config("op3")
    clip = demo.frames(0, 60)
    dt = 1.0 / clip.fps
    runs = {}
    for kind in ("clean", "glitch", "far", "stays"):
        step = RetargetStep(config, "default", clip.skeleton)
        roots = []
        for t in range(clip.num_frames):
            root = clip.root_pos[t].copy()
            if kind == "glitch" and t == 30:
                root[0] += 50.0
            if kind == "far" and t == 30:
                root[0] += 1e6
            if kind == "stays" and t >= 30:
                root[2] += 3.0
            roots.append(step(clip.local_quats[t], root, dt, settle=t == 0).root_pos)
        runs[kind] = np.array(roots)
    for kind in ("glitch", "far", "stays"):  # without it: 9.3 m off after the 50 m glitch
        off = np.linalg.norm(runs[kind] - runs["clean"], axis=1)
        assert off.max() < 0.003, (kind, off.max())


def test_units_a_user_mixes_up_are_refused(step: RetargetStep, demo: HumanMotion) -> None:
    """Milliseconds as dt_s (the optimizer's steps went to 4.9x the velocity limit) and a start
    pose in degrees (q came back at 15 rad): one-line errors that say what to pass."""
    from robot_retarget.errors import SolveError

    quats, root = demo.local_quats[0], demo.root_pos[0]
    with pytest.raises(SolveError, match=r"milliseconds\? then pass 0.008"):
        step(quats, root, 8.0)
    with pytest.raises(SolveError, match=r"more than a turn.*radians"):
        step.reset(np.degrees(step.config.init_pose) + 400.0)
    with pytest.raises(SolveError, match=r"q_prev: .* more than a turn"):
        step(quats, root, 0.008, q_prev=np.full(step.config.num_joints, 30.0))
    for bad in (None, float("nan"), -0.008):
        with pytest.raises(SolveError, match="finite positive number of seconds"):
            step(quats, root, bad)  # type: ignore[arg-type]
    step.reset()
    assert np.isfinite(step(quats, root, 0.008).q).all()  # the step goes on
