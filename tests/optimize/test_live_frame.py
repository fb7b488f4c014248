"""The live path's compiled frame program (targets, parameters, velocity box in one call):
the same commands as the numpy targets and writers, the same box, the same refusals."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SolveError
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.optimize import Retargeter
from robot_retarget.optimize.limits import velocity_box
from robot_retarget.optimize.live_frame import LiveFrameSolver, NotAffineError
from robot_retarget.optimize.targets import FrameTargetBuilder, FrameTargets
from robot_retarget.optimize.terms import BoneDirectionTerm
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig


def _live(retargeter: Retargeter) -> LiveFrameSolver:
    builder = FrameTargetBuilder(retargeter.problem, robot_canonical_skeleton(retargeter.config))
    return LiveFrameSolver(retargeter, builder)


@pytest.mark.parametrize(("robot", "warm_start_step"), [("op3", 1.0), ("poppy", 1.0), ("op3", 0.0)])
def test_the_same_commands_as_the_numpy_path(
    robot: str, warm_start_step: float, request: pytest.FixtureRequest
) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    if warm_start_step != 1.0:  # the default moves the start on by the last step; 0: it does not
        config = dataclasses.replace(
            config, retarget={**config.retarget, "warm_start_step": warm_start_step}
        )
    motion = demo_motion(fps=config.control_rate_hz).frames(0, 150)
    dt = 1.0 / config.control_rate_hz
    fast, ref = (
        RetargetStep(config, "copy", motion.skeleton, frame_program=program)
        for program in (True, False)
    )
    assert fast.live is not None
    assert ref.live is None
    for s in (fast, ref):
        s.reset()
    for t in range(motion.num_frames):
        a = fast(motion.local_quats[t], motion.root_pos[t], dt)
        b = ref(motion.local_quats[t], motion.root_pos[t], dt)
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.trunk_frame, b.trunk_frame, rtol=0, atol=1e-12)
        assert a.solve.status == b.solve.status
    # The same history, so the next solve starts from the same place.
    for x, y in zip(fast.retargeter.history(), ref.retargeter.history(), strict=True):
        np.testing.assert_array_equal(x, y)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    offset=st.floats(-0.6, 0.6),
    spread=st.floats(0.0, 1.0),
    dt=st.floats(1e-3, 0.1),
    seed=st.integers(0, 2**16),
)
def test_the_box_is_the_velocity_box(
    op3_retargeter: Retargeter, offset: float, spread: float, dt: float, seed: int
) -> None:
    """Anywhere, limits' outside included (an empty interval collapses toward the limits)."""
    r = op3_retargeter
    live = _frame_solver(r)
    rng = np.random.default_rng(seed)
    span = r.upper - r.lower
    q_prev = r.lower + span * rng.uniform(-spread, 1.0 + spread, r.num_joints) + offset
    rest = np.tile([1.0, 0.0, 0.0, 0.0], (22, 1))
    r.reset()
    assert live.write(rest, dt, q_prev=q_prev)
    lo, hi = velocity_box(q_prev, r.lower, r.upper, r.max_velocity * dt)
    s = r.online_solver
    np.testing.assert_array_equal(s.lbx, lo)
    np.testing.assert_array_equal(s.ubx, hi)
    assert np.all(s.lbx <= s.x0)
    assert np.all(s.x0 <= s.ubx)
    result = r.solve_written()
    assert np.all(lo <= result.q)
    assert np.all(result.q <= hi)


_FRAME_SOLVERS: dict[int, LiveFrameSolver] = {}


def _frame_solver(r: Retargeter) -> LiveFrameSolver:
    # One per retargeter: building one reads the writers' map (~130 writes).
    if id(r) not in _FRAME_SOLVERS:
        _FRAME_SOLVERS[id(r)] = _live(r)
    return _FRAME_SOLVERS[id(r)]


def test_a_degenerate_frame_takes_the_numpy_path(op3: RobotConfig) -> None:
    """A root "rotation" that flattens every vector onto one axis (a non-unit quaternion: the
    step refuses one as input, but nothing promises the network's output is unit) leaves no
    trunk frame: the graph's guard sends the frame to the numpy targets and their fallbacks,
    and the command is the numpy path's."""
    motion = demo_motion(fps=op3.control_rate_hz).frames(0, 3)
    fast, ref = (
        RetargetStep(op3, "copy", motion.skeleton, frame_program=program)
        for program in (True, False)
    )
    flat = np.tile([1.0, 0.0, 0.0, 0.0], (22, 1))
    flat[0] = (0.0, np.sqrt(0.5), 0.0, 0.0)  # maps (x, y, z) to (x, 0, 0)
    assert fast.live is not None
    assert not fast.live.write(flat, 0.008)
    network_gives_flat = [False]
    for s in (fast, ref):
        s.reset()
        s.online.step = lambda q, root: (  # type: ignore[method-assign]
            flat if network_gives_flat[0] else q,
            root,
        )
    for k, degenerate in enumerate((False, True, False)):
        network_gives_flat[0] = degenerate
        a = fast(motion.local_quats[k], motion.root_pos[0], 0.008)
        b = ref(motion.local_quats[k], motion.root_pos[0], 0.008)
        # Bit for bit: a degenerate frame's write leaves the start point (which the numpy
        # path moves on from) as it was.
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.trunk_frame, b.trunk_frame)


@pytest.mark.parametrize(
    ("quats", "dt", "match"),
    [
        (np.full((22, 4), np.nan), 0.008, "NaN"),
        (np.zeros((21, 4)), 0.008, "shape"),
        (np.tile([1.0, 0, 0, 0], (22, 1)), 0.0, "dt_s"),
        (np.tile([1.0, 0, 0, 0], (22, 1)), float("nan"), "dt_s"),
    ],
)
def test_bad_input_writes_nothing(
    op3_retargeter: Retargeter, quats: FloatArray, dt: float, match: str
) -> None:
    r = op3_retargeter
    live = _frame_solver(r)
    s = r.online_solver
    before = (s.p.copy(), s.lbx.copy(), s.ubx.copy(), s.x0.copy())
    with pytest.raises(SolveError, match=match):
        live.write(quats, dt)
    for a, b in zip(before, (s.p, s.lbx, s.ubx, s.x0), strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_writer_that_is_not_affine_is_refused(
    op3_retargeter: Retargeter, monkeypatch: pytest.MonkeyPatch
) -> None:
    def squared(self: BoneDirectionTerm, params: Mapping[str, FloatArray],
                targets: FrameTargets) -> None:  # fmt: skip
        params["target"][:] = np.asarray(targets.directions).ravel() ** 2

    monkeypatch.setattr(BoneDirectionTerm, "write_frame", squared)
    s = op3_retargeter.online_solver
    before = s.p.copy()
    with pytest.raises(NotAffineError) as info:
        _live(op3_retargeter)
    assert info.value.error > 0.0
    np.testing.assert_array_equal(s.p, before)  # the probe writes were undone
