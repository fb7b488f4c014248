"""The papers' copy baselines: rotations and root motion copied (optionally scaled)."""

from __future__ import annotations

from collections.abc import Callable

import torch

from robot_retarget.nn.features import compute_features, skeleton_height
from robot_retarget.nn.models.copy import CopyModel, CopyScaledModel

Motion = Callable[..., tuple[torch.Tensor, torch.Tensor]]


def test_copy_reproduces_the_source(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    src, tgt = skeleton_pair
    quats, root = motion(2, 15, seed=2)
    out = CopyModel()(quats, root, src, tgt)
    dots = torch.sum(out.local_quats * quats, dim=-1).abs()  # same rotations (sign free)
    torch.testing.assert_close(dots, torch.ones_like(dots), atol=1e-5, rtol=0)
    torch.testing.assert_close(out.local_quats[..., 1:, :], quats[..., 1:, :])
    torch.testing.assert_close(out.root_pos, root, atol=1e-5, rtol=0)


def test_copy_scaled_scales_root_displacement_by_height_ratio(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    src, tgt = skeleton_pair
    quats, root = motion(2, 15, seed=4)
    out = CopyScaledModel()(quats, root, src, tgt)
    ratio = skeleton_height(tgt) / skeleton_height(src)
    assert not torch.allclose(ratio, torch.ones_like(ratio))
    expected = root[:, :1] + (root - root[:, :1]) * ratio[:, None, None]
    torch.testing.assert_close(out.root_pos, expected, atol=1e-5, rtol=0)
    # Rotations and yaw rate are untouched.
    torch.testing.assert_close(out.local_quats[..., 1:, :], quats[..., 1:, :])
    feats = compute_features(quats, root, src)
    torch.testing.assert_close(out.features.root_vel[..., 3], feats.root_vel[..., 3])


def test_copy_scaled_is_copy_for_the_same_skeleton(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    src, _ = skeleton_pair
    quats, root = motion(2, 9, seed=6)
    a = CopyModel()(quats, root, src, src)
    b = CopyScaledModel()(quats, root, src, src)
    torch.testing.assert_close(a.root_pos, b.root_pos)
    assert CopyModel().config() == {}
    assert not CopyModel.trainable
    assert not list(CopyScaledModel().parameters())
