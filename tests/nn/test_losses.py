"""Loss terms of NKN and PMnet: values on hand-made cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.losses import (
    TWIST_ALPHA_RAD,
    discriminator_loss,
    end_effector_weights,
    generator_adversarial_loss,
    mean_point_trajectory,
    perceptual_pose_loss,
    reconstruction_loss,
    squared_error,
    twist_axes,
    twist_loss,
    velocity_smoothing_loss,
)
from robot_retarget.skeleton.canonical import Joint, default_canonical_skeleton

SKELETON = default_canonical_skeleton()


def _offsets() -> torch.Tensor:
    return torch.tensor(np.asarray(SKELETON.offsets), dtype=torch.float64)[None]


def _identity(frames: int = 3) -> torch.Tensor:
    return qt.identity((1, frames, 22), dtype=torch.float64)


def test_twist_axes_follow_the_bones() -> None:
    axes = twist_axes(_offsets())[0]
    torch.testing.assert_close(axes[Joint.LeftArm], torch.tensor([1.0, 0, 0], dtype=torch.float64))
    torch.testing.assert_close(
        axes[Joint.RightForeArm], torch.tensor([-1.0, 0, 0], dtype=torch.float64)
    )
    torch.testing.assert_close(
        axes[Joint.LeftUpLeg], torch.tensor([0.0, -1, 0], dtype=torch.float64)
    )
    # Spine2 → its first child, the neck; Head (a leaf) → its own bone.
    torch.testing.assert_close(axes[Joint.Spine2], torch.tensor([0.0, 1, 0], dtype=torch.float64))
    torch.testing.assert_close(axes[Joint.Head], torch.tensor([0.0, 1, 0], dtype=torch.float64))
    # A zero-length chain falls back to the up axis.
    zero = _offsets().clone()
    zero[0, Joint.LeftForeArm] = 0.0
    zero[0, Joint.LeftArm] = 0.0
    torch.testing.assert_close(
        twist_axes(zero)[0, Joint.LeftArm], torch.tensor([0.0, 1, 0], dtype=torch.float64)
    )


@settings(max_examples=25)
@given(angle_deg=st.floats(-179.0, 179.0))
def test_twist_loss_penalises_twist_beyond_alpha_only(angle_deg: float) -> None:
    q = _identity()
    twist = qt.from_axis_angle(
        torch.tensor([1.0, 0, 0], dtype=torch.float64), math.radians(angle_deg)
    )
    q[:, :, Joint.LeftArm] = twist  # about the upper arm's own axis
    loss = float(twist_loss(q, _offsets())[0])
    excess = max(0.0, abs(math.radians(angle_deg)) - TWIST_ALPHA_RAD)
    assert loss == pytest.approx(excess**2, abs=1e-9)


def test_swing_is_not_twist() -> None:
    q = _identity()
    swing = qt.from_axis_angle(torch.tensor([0.0, 0, 1], dtype=torch.float64), math.radians(150.0))
    q[:, :, Joint.LeftArm] = swing
    q[:, :, Joint.Hips] = swing  # the root orientation is free
    assert float(twist_loss(q, _offsets())[0]) == pytest.approx(0.0, abs=1e-12)


def test_end_effector_chains_are_double_weighted() -> None:
    w = end_effector_weights()
    trunk = [Joint.Hips, Joint.Spine, Joint.Spine1, Joint.Spine2]
    assert all(float(w[j]) == 1.0 for j in trunk)
    assert float(w.sum()) == 1.0 * len(trunk) + 2.0 * (22 - len(trunk))
    assert float(w[Joint.LeftShoulder]) == 2.0
    assert float(w[Joint.Neck]) == 2.0


def test_reconstruction_weights_errors() -> None:
    target = torch.zeros(1, 2, 22, 3)
    hand = target.clone()
    hand[:, :, Joint.RightHand, 0] = 0.1
    spine = target.clone()
    spine[:, :, Joint.Spine, 0] = 0.1
    w = end_effector_weights()
    assert float(reconstruction_loss(hand, target, w)[0]) == pytest.approx(2 * 0.01)
    assert float(reconstruction_loss(spine, target, w)[0]) == pytest.approx(0.01)


def test_squared_error_sums_features_and_averages_frames() -> None:
    a = torch.zeros(2, 4, 3)
    b = torch.ones(2, 4, 3)
    b[1] *= 2.0
    torch.testing.assert_close(squared_error(a, b), torch.tensor([3.0, 12.0]))
    torch.testing.assert_close(perceptual_pose_loss(a, b), torch.tensor([3.0, 12.0]))


def test_velocity_smoothing() -> None:
    constant = torch.ones(1, 5, 4)
    assert float(velocity_smoothing_loss(constant)[0]) == 0.0
    ramp = torch.arange(5.0)[None, :, None].expand(1, 5, 4)
    assert float(velocity_smoothing_loss(ramp)[0]) == pytest.approx(4.0)


def test_mean_point_trajectory_is_scale_free() -> None:
    g = torch.Generator().manual_seed(0)
    local = torch.randn(2, 6, 22, 3, generator=g)
    vel = torch.randn(2, 6, 4, generator=g)
    scale = torch.tensor([1.0, 2.0])
    a = mean_point_trajectory(local, vel, scale)
    k = 0.3
    b = mean_point_trajectory(local * k, torch.cat([vel[..., :3] * k, vel[..., 3:]], -1), scale * k)
    torch.testing.assert_close(a, b, atol=1e-5, rtol=0)
    still = mean_point_trajectory(local, torch.zeros(2, 6, 4), scale)
    torch.testing.assert_close(still, local.mean(-2) / scale[:, None, None])


def test_gan_terms_are_the_papers_logs() -> None:
    real = torch.tensor([2.0, -1.0, 0.0])
    fake = torch.tensor([-3.0, 0.5, 0.0])
    d_real, d_fake = torch.sigmoid(real), torch.sigmoid(fake)
    expected = -(torch.log(d_real) + torch.log(1 - d_fake))
    torch.testing.assert_close(discriminator_loss(real, fake), expected)
    torch.testing.assert_close(generator_adversarial_loss(fake), torch.log(1 - d_fake))
    # Stable where the naive form overflows.
    assert torch.isfinite(generator_adversarial_loss(torch.tensor([200.0]))).all()
