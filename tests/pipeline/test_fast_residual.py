"""The numpy residual model equals the torch model's online step (to float32 rounding)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import torch
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.nn.inference import LoadedModel
from robot_retarget.nn.models.registry import build_model
from robot_retarget.nn.models.residual import ResidualRetargeter
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.loader import online_retargeter
from robot_retarget.runtime.model import OnlineStep
from robot_retarget.runtime.residual import FastResidualRetargeter
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.foot_lock_spec import LEGS
from tests.pipeline.stream_equality import assert_same_stream, clear_of_half_turns

# float32 torch against float64 numpy; outputs are unit quaternions and metres.
TOL = 2e-5


def _trained_like(seed: int = 0) -> LoadedModel:
    """A residual model whose zero-initialised layers and root filter have random values,
    so every learned path (denoiser weights, correction, filter taps) is exercised."""
    torch.manual_seed(seed)
    model = build_model("residual", hidden_size=64, num_layers=3, denoiser_hidden=16)
    with torch.no_grad():
        for param in model.parameters():
            if not param.any():
                param.normal_(0.0, 0.05)
        for norm in (model.pose_norm, model.rot_norm, model.offset_norm):
            norm.mean.normal_(0.0, 0.1)
            norm.std.uniform_(0.5, 2.0)
    return LoadedModel(name="residual", model=model.eval())


def _assert_same_stream(
    model: LoadedModel, src: np.ndarray, tgt: np.ndarray, quats: np.ndarray, root: np.ndarray
) -> None:
    assert_same_stream(model, src, tgt, quats, root, FastResidualRetargeter, TOL)


def test_equals_the_torch_model_on_the_demo(demo: HumanMotion, op3: RobotConfig) -> None:
    tgt = robot_canonical_skeleton(op3).offsets
    n = 120
    _assert_same_stream(
        _trained_like(), demo.skeleton.offsets, tgt, demo.local_quats[:n], demo.root_pos[:n]
    )


def test_the_demo_exercises_the_foot_lock(demo: HumanMotion, op3: RobotConfig) -> None:
    """The equality above covers the lock: on the demo its legs differ from the unlocked model's
    (both through the numpy step)."""
    tgt = robot_canonical_skeleton(op3).offsets
    outputs = []
    for lock in (True, False):
        model = _trained_like()
        assert isinstance(model.model, ResidualRetargeter)
        if not lock:
            model.model.lock = None
        outputs.append(_rotations(online_retargeter(model, demo.skeleton.offsets, tgt), demo))
    _assert_only_the_legs_differ(*outputs)


def _rotations(step: OnlineStep, motion: HumanMotion) -> np.ndarray:
    frames = zip(motion.local_quats, motion.root_pos, strict=True)
    return np.array([step.step(q, r)[0] for q, r in frames])


def _assert_only_the_legs_differ(a: np.ndarray, b: np.ndarray) -> None:
    angle = quat.angle_between(a, b)
    legs = [j for leg in LEGS for j in leg]
    assert angle[:, legs].max() > 1e-3
    assert np.delete(angle, legs, axis=1).max() < 1e-9


def test_the_foot_lock_judges_speed_at_the_rate_it_runs(
    demo: HumanMotion, op3: RobotConfig
) -> None:
    """The same frames at four times the rate are four times slower motion: more of it counts
    as planted, so the legs differ (and only they); a rate that is not positive is refused."""
    tgt = robot_canonical_skeleton(op3).offsets
    weights = _trained_like().model.export_weights()
    _assert_only_the_legs_differ(
        *(
            _rotations(
                FastResidualRetargeter(weights, demo.skeleton.offsets, tgt, frame_rate_hz=rate),
                demo,
            )
            for rate in (30.0, 120.0)
        )
    )
    with pytest.raises(ValueError, match="frame_rate_hz"):
        FastResidualRetargeter(weights, demo.skeleton.offsets, tgt, frame_rate_hz=0.0)


@settings(max_examples=10, deadline=None)
@given(
    arrays(np.float64, (6, 22, 3), elements=st.floats(-3.1, 3.1)),
    arrays(np.float64, (6, 3), elements=st.floats(-5.0, 5.0)),
)
def test_equals_the_torch_model_on_wild_streams(rotvecs: np.ndarray, root: np.ndarray) -> None:
    """Arbitrary rotations (dropped joints, flips) and root jumps."""
    src = default_canonical_skeleton().offsets
    quats = quat.from_rotation_vector(rotvecs)
    assume(clear_of_half_turns(quats))
    _assert_same_stream(_trained_like(1), src, 0.4 * src, quats, root)


def test_wrong_shapes_raise(demo: HumanMotion) -> None:
    src = demo.skeleton.offsets
    model = _trained_like()
    assert isinstance(model.model, ResidualRetargeter)
    fast = online_retargeter(model, src, src)
    with pytest.raises(ValueError, match="local_quats"):
        fast.step(np.zeros((21, 4)), np.zeros(3))
    with pytest.raises(ValueError, match="root_pos"):
        fast.step(demo.local_quats[0], np.zeros(2))
    with pytest.raises(ValueError, match="target_offsets"):
        FastResidualRetargeter(model.model.export_weights(), src, src[:5])


def test_inputs_are_not_modified(demo: HumanMotion) -> None:
    fast = online_retargeter(_trained_like(), demo.skeleton.offsets, demo.skeleton.offsets)
    quats = demo.local_quats[5].copy()
    fast.step(quats, demo.root_pos[5])
    np.testing.assert_array_equal(quats, demo.local_quats[5])


_Q = ca.SX.sym("q", 4)
_R = ca.SX.sym("r", 3)
_SX_LOG = ca.Function("log", [_Q], [ca.vertcat(*sq.rotvec([_Q[i] for i in range(4)]))])
_SX_EXP = ca.Function("exp", [_R], [ca.vertcat(*sq.from_rotvec([_R[i] for i in range(3)]))])


@settings(max_examples=50, deadline=None)
@given(
    arrays(np.float64, (8, 3), elements=st.floats(-3.1, 3.1)),
    st.floats(1e-12, 1.0),
)
def test_rotation_vectors_agree_with_the_geometry_module(
    rotvecs: np.ndarray, shrink: float
) -> None:
    """The compiled steps' shortest-arc log and exponential (geometry.symbolic_quaternion),
    for large, tiny and zero rotations and both signs of q."""

    def _rotvec(q: np.ndarray) -> np.ndarray:
        return np.array([_SX_LOG(row).full().ravel() for row in q])

    def _from_rotvec(r: np.ndarray) -> np.ndarray:
        return np.array([_SX_EXP(row).full().ravel() for row in r])

    for r in (rotvecs, rotvecs * shrink, np.zeros((2, 3))):
        q = quat.from_rotation_vector(r)
        for signed in (q, -q):
            np.testing.assert_allclose(
                _rotvec(signed), quat.to_rotation_vector(signed), rtol=1e-9, atol=1e-15
            )
        np.testing.assert_allclose(_from_rotvec(r), q, rtol=1e-12, atol=1e-15)
