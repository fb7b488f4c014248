"""Papers' motion features: heading removal, root velocities and their integration."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import (
    FeatureStream,
    FrameKinematics,
    apply_heading,
    compute_features,
    heading_yaw,
    integrate_root,
    local_positions,
    pmnet_scale,
    remove_heading,
    root_velocity,
    skeleton_height,
    wrap_angle,
    yaw_mul,
    yaw_quat,
    yaw_rotate,
)
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import forward_kinematics

SKELETON = default_canonical_skeleton()


def _motion(batch: int, frames: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Random rotations with a turning root, float64 (exactness checks)."""
    g = torch.Generator().manual_seed(seed)
    rv = 0.5 * torch.randn(batch, frames, 22, 3, generator=g, dtype=torch.float64)
    quats = qt.from_rotation_vector(rv)
    root = torch.cumsum(0.05 * torch.randn(batch, frames, 3, generator=g, dtype=torch.float64), 1)
    return quats, root


def _offsets(batch: int) -> torch.Tensor:
    return torch.tensor(np.asarray(SKELETON.offsets))[None].repeat(batch, 1, 1)


@settings(max_examples=30)
@given(yaw=st.floats(-math.pi + 1e-6, math.pi))
def test_heading_of_a_pure_yaw_is_that_yaw(yaw: float) -> None:
    q = yaw_quat(torch.tensor(yaw, dtype=torch.float64))
    assert float(heading_yaw(q)) == pytest.approx(yaw, abs=1e-9)


def test_heading_ignores_pitch_and_roll_about_the_left_axis() -> None:
    """Bending forward (about the left-right axis +X) keeps the heading."""
    yaw = torch.tensor(0.7, dtype=torch.float64)
    bend = qt.from_axis_angle(torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64), 0.9)
    assert float(heading_yaw(qt.mul(yaw_quat(yaw), bend))) == pytest.approx(0.7, abs=1e-12)


def test_local_pose_is_numpy_fk_of_heading_free_rotations() -> None:
    quats, root = _motion(2, 5, 0)
    feats = compute_features(quats, root, _offsets(2))
    for b in range(2):
        free = remove_heading(quats[b], heading_yaw(quats[b, :, 0])).numpy()
        pos, _ = forward_kinematics(SKELETON, free)
        np.testing.assert_allclose(feats.local_pos[b].numpy(), pos, atol=1e-12)
    torch.testing.assert_close(
        feats.local_pos[..., 0, :], torch.zeros(2, 5, 3, dtype=torch.float64)
    )
    assert feats.x.shape == (2, 5, 70)
    assert feats.pose_flat.shape == (2, 5, 66)


@settings(max_examples=15)
@given(turn=st.floats(-3.0, 3.0), shift=st.tuples(*[st.floats(-5.0, 5.0)] * 3))
def test_features_do_not_depend_on_where_and_which_way(
    turn: float, shift: tuple[float, float, float]
) -> None:
    """Rotating the whole motion about Y and moving it leaves every feature but yaw unchanged."""
    quats, root = _motion(1, 6, 1)
    r = yaw_quat(torch.tensor(turn, dtype=torch.float64))
    quats2 = torch.cat([qt.mul(r, quats[..., :1, :]), quats[..., 1:, :]], dim=-2)
    root2 = qt.rotate(r, root) + torch.tensor(shift, dtype=torch.float64)
    a = compute_features(quats, root, _offsets(1))
    b = compute_features(quats2, root2, _offsets(1))
    torch.testing.assert_close(a.local_pos, b.local_pos, atol=1e-9, rtol=0)
    torch.testing.assert_close(a.root_vel, b.root_vel, atol=1e-9, rtol=0)
    torch.testing.assert_close(
        wrap_angle(b.yaw - a.yaw), torch.full_like(a.yaw, turn), atol=1e-9, rtol=0
    )


@settings(max_examples=20)
@given(seed=st.integers(0, 10_000))
def test_integration_inverts_root_velocity(seed: int) -> None:
    quats, root = _motion(2, 9, seed)
    yaw = heading_yaw(quats[..., 0, :])
    vel = root_velocity(root, yaw)
    assert float(vel[:, 0].abs().max()) == 0.0
    pos, yaw2 = integrate_root(vel, root[:, 0], yaw[:, 0])
    torch.testing.assert_close(pos, root, atol=1e-10, rtol=0)
    torch.testing.assert_close(wrap_angle(yaw2 - yaw), torch.zeros_like(yaw), atol=1e-10, rtol=0)


def test_apply_heading_undoes_remove_heading() -> None:
    quats, _ = _motion(2, 4, 2)
    yaw = torch.rand(2, 4, dtype=torch.float64) * 6 - 3
    torch.testing.assert_close(apply_heading(remove_heading(quats, yaw), yaw), quats)


def test_stream_matches_clip_features_and_integration() -> None:
    quats, root = _motion(2, 8, 3)
    offs = _offsets(2)
    clip = compute_features(quats, root, offs)
    stream = FeatureStream()
    for t in range(8):
        f = stream.push(quats[:, t], root[:, t], offs)
        torch.testing.assert_close(f.local_pos, clip.local_pos[:, t])
        torch.testing.assert_close(f.root_vel, clip.root_vel[:, t])
        torch.testing.assert_close(f.local_quats, clip.local_quats[:, t])
        pos, _ = stream.integrate(clip.root_vel[:, t])
        torch.testing.assert_close(pos, root[:, t], atol=1e-10, rtol=0)
    stream.reset()
    first = stream.push(quats[:, 3], root[:, 3], offs)
    assert float(first.root_vel.abs().max()) == 0.0


def test_stream_integrate_needs_a_frame() -> None:
    with pytest.raises(RuntimeError, match="before push"):
        FeatureStream().integrate(torch.zeros(1, 4))


def test_features_of_frame_t_ignore_later_frames() -> None:
    quats, root = _motion(1, 10, 4)
    other_q, other_r = _motion(1, 10, 5)
    a = compute_features(quats, root, _offsets(1))
    b = compute_features(
        torch.cat([quats[:, :6], other_q[:, 6:]], 1),
        torch.cat([root[:, :6], other_r[:, 6:]], 1),
        _offsets(1),
    )
    torch.testing.assert_close(a.x[:, :6], b.x[:, :6])


def test_skeleton_measures() -> None:
    offs = _offsets(1)
    rest = SKELETON.rest_positions()
    assert float(skeleton_height(offs)[0]) == pytest.approx(rest[:, 1].max() - rest[:, 1].min())
    assert float(skeleton_height(offs * 0.5)[0]) == pytest.approx(
        0.5 * float(skeleton_height(offs)[0])
    )
    lengths = SKELETON.bone_lengths()
    idx = [
        SKELETON.index(n)
        for n in ("Hips", "Spine", "Spine1", "Spine2", "Neck", "LeftUpLeg", "LeftLeg", "LeftFoot")
    ]
    assert float(pmnet_scale(offs)[0]) == pytest.approx(lengths[idx].sum())


def test_shape_errors_name_the_argument() -> None:
    quats, root = _motion(1, 3, 0)
    with pytest.raises(ValueError, match="local_quats"):
        compute_features(quats[0], root, _offsets(1))
    with pytest.raises(ValueError, match="offsets"):
        compute_features(quats, root, _offsets(2))


def test_float32_gradients_flow() -> None:
    quats, root = _motion(1, 4, 6)
    q = quats.float().requires_grad_()
    feats = compute_features(q, root.float(), _offsets(1).float())
    (feats.local_pos.sum() + feats.root_vel.sum()).backward()
    assert q.grad is not None
    assert torch.isfinite(q.grad).all()
    assert feats.local_pos.dtype == torch.float32


@settings(max_examples=15)
@given(seed=st.integers(0, 10_000), scale=st.floats(0.1, 3.0))
def test_frame_kinematics_equals_fk_layer(seed: int, scale: float) -> None:
    quats, _ = _motion(3, 1, seed)
    offs = _offsets(3) * scale
    pos, root_rot = FrameKinematics().positions(quats[:, 0], offs)
    torch.testing.assert_close(pos, local_positions(quats, offs)[:, 0], atol=1e-12, rtol=0)
    torch.testing.assert_close(root_rot, qt.to_matrix(quats[:, 0, 0]), atol=1e-12, rtol=0)


@settings(max_examples=25)
@given(yaw=st.floats(-7.0, 7.0), seed=st.integers(0, 1000))
def test_yaw_shortcuts_equal_quaternion_ops(yaw: float, seed: int) -> None:
    g = torch.Generator().manual_seed(seed)
    q = qt.normalize(torch.randn(5, 4, generator=g, dtype=torch.float64))
    v = torch.randn(5, 3, generator=g, dtype=torch.float64)
    psi = torch.full((5,), yaw, dtype=torch.float64)
    torch.testing.assert_close(yaw_mul(psi, q), qt.mul(yaw_quat(psi), q))
    torch.testing.assert_close(yaw_rotate(v, psi), qt.rotate(yaw_quat(psi), v))


def test_frame_kinematics_gradients_equal_the_fk_layer() -> None:
    """NKN trains through FrameKinematics: its gradients must be the FK layer's.

    The quadratic matrix form equals the FK layer on unit quaternions only, so gradients agree
    through the normalisation every network output passes (tangent to the unit sphere).
    """
    quats, _ = _motion(2, 1, 9)
    raw_quats = quats[:, 0] * torch.linspace(0.5, 2.0, 22, dtype=torch.float64)[:, None]
    offs = _offsets(2)
    weights = torch.randn(2, 22, 3, dtype=torch.float64)
    grads = []
    for use_frame in (True, False):
        raw = raw_quats.clone().requires_grad_()
        o = offs.clone().requires_grad_()
        q = qt.normalize(raw)
        if use_frame:
            pos = FrameKinematics().positions(q, o)[0]
        else:
            pos = local_positions(q[:, None], o)[:, 0]
        (pos * weights).sum().backward()
        grads.append((raw.grad, o.grad))
    torch.testing.assert_close(grads[0][0], grads[1][0], atol=1e-12, rtol=0)
    torch.testing.assert_close(grads[0][1], grads[1][1], atol=1e-12, rtol=0)


def test_caches_built_in_inference_mode_still_train() -> None:
    """Constants first built under torch.inference_mode() must not break autograd later."""
    from robot_retarget.nn import features

    features._ancestor_matrix.cache_clear()
    with torch.inference_mode():
        fk = FrameKinematics()
        skeleton_height(_offsets(1).float())
    offs = _offsets(1).float().requires_grad_()  # float32: .to() then keeps cached tensors
    quats, _ = _motion(1, 1, 0)
    pos, _ = fk.positions(quats[:, 0].float(), offs)
    (pos.sum() + skeleton_height(offs).sum()).backward()
    assert offs.grad is not None
    assert torch.isfinite(offs.grad).all()
