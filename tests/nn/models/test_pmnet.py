"""PMnet specifics: q_B = q_A ⊗ Δq, scale-normalised causal movement regressor."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import compute_features, pmnet_scale
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.pmnet import (
    PMnet,
    denormalize_movement,
    hamilton,
    normalize_movement,
)

Motion = Callable[..., tuple[torch.Tensor, torch.Tensor]]


def test_target_rotation_is_hamilton_product_of_source_and_delta(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model("pmnet").eval()
    assert isinstance(model, PMnet)
    src, tgt = skeleton_pair
    quats, root = motion(2, 5)
    feats = compute_features(quats, root, src)
    with torch.no_grad():
        pred = model.retarget(feats, src, tgt)
        phi = model.encode_pose(feats.pose_flat)
        delta_in = torch.cat(
            [phi, model.offset_norm(tgt.flatten(-2))[:, None].expand(-1, 5, -1)], -1
        )
        delta = qt.normalize(model.to_delta(delta_in).view(2, 5, 22, 4))
    torch.testing.assert_close(pred.local_quats, qt.mul(pred.extras["q_a"], delta))
    torch.testing.assert_close(pred.extras["phi_a"], phi)


def test_root_velocity_scales_with_the_target(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """Movement is regressed in scale-free units, then multiplied by S_B: a target k times
    larger moves k times further per frame, with the same yaw rate."""
    model = tiny_model("pmnet").eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 8)
    feats = compute_features(quats, root, src)
    with torch.no_grad():
        small = model.retarget(feats, src, tgt).root_vel
        # Only the movement is compared; Δq also sees ref_B, which does not matter here.
        large = model.retarget(feats, src, tgt * 3.0).root_vel
    torch.testing.assert_close(large[..., :3], 3.0 * small[..., :3], atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(large[..., 3], small[..., 3])


def test_scale_factor_uses_trunk_and_left_leg(
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    src, _ = skeleton_pair
    s = pmnet_scale(src)
    # Default human: spine 0.10+0.12+0.12, neck 0.16, hip sqrt(0.09²+0.05²), leg 0.42+0.41.
    expected = 0.10 + 0.12 + 0.12 + 0.16 + (0.09**2 + 0.05**2) ** 0.5 + 0.42 + 0.41
    torch.testing.assert_close(s, torch.full((2,), expected), atol=1e-6, rtol=0)
    changed = src.clone()
    changed[:, 8] *= 2.0  # the left forearm is not in H
    torch.testing.assert_close(pmnet_scale(changed), s)


def test_movement_normalisation_round_trip() -> None:
    vel = torch.randn(3, 7, 4)
    scale = torch.tensor([0.5, 1.0, 2.0])
    nv = normalize_movement(vel, scale)
    torch.testing.assert_close(nv[..., 3], vel[..., 3])
    torch.testing.assert_close(nv[0, ..., :3], vel[0, ..., :3] / 0.5)
    torch.testing.assert_close(denormalize_movement(nv, scale), vel)


def test_centred_movement_has_no_online_path(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    model = PMnet(hidden_size=8, num_layers=1, movement_channels=4, causal_movement=False).eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 6)
    with torch.no_grad():
        out = model(quats, root, src, tgt)  # the clip path works (paper's centred convs)
    assert out.root_pos.shape == (2, 6, 3)
    model.reset()
    with pytest.raises(RuntimeError, match="future frames"):
        model.step(quats[:, 0], root[:, 0], src, tgt)


def test_paper_defaults() -> None:
    model = PMnet()
    assert model.config()["hidden_size"] == 512
    linears = [m for m in model.pose_encoder if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in linears] == [(66, 512)] + [(512, 512)] * 3
    assert model.to_quat.out_features == 88
    assert model.to_delta.out_features == 88
    assert model.movement.conv1.out_channels == 128
    assert model.movement.conv1.kernel_size == (3,)


@settings(max_examples=20)
@given(seed=st.integers(0, 10_000))
def test_online_hamilton_product_equals_quaternion_mul(seed: int) -> None:
    g = torch.Generator().manual_seed(seed)
    a = torch.randn(3, 22, 4, generator=g, dtype=torch.float64)
    b = torch.randn(3, 22, 4, generator=g, dtype=torch.float64)
    torch.testing.assert_close(hamilton(a, b), qt.mul(a, b))


def test_online_constants_follow_a_new_target(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """The per-skeleton terms cached by step() are recomputed when the skeleton changes."""
    model = tiny_model("pmnet").eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 2)
    with torch.no_grad():
        expected = model(quats, root, src, tgt * 2.0)
    model.reset()
    with torch.inference_mode():
        model.step(quats[:, 0], root[:, 0], src, tgt)
        second = model.step(quats[:, 1], root[:, 1], src, tgt * 2.0)
    # The pose path is per frame: frame 1's joint rotations depend on frame 1 and ref_B only.
    torch.testing.assert_close(second.local_quats[:, 1:], expected.local_quats[:, 1, 1:])
