"""The papers' convolutional discriminators: layer lengths, inputs, logits."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.nn.discriminators import NKNDiscriminator, PMnetDiscriminator, same_pad
from robot_retarget.nn.features import compute_features

Motion = Callable[..., tuple[torch.Tensor, torch.Tensor]]


@settings(max_examples=40)
@given(length=st.integers(1, 200), kernel=st.integers(1, 6), stride=st.integers(1, 3))
def test_same_pad_gives_ceil_length(length: int, kernel: int, stride: int) -> None:
    x = torch.zeros(1, 1, length)
    padded = same_pad(x, kernel, stride)
    out = torch.nn.functional.conv1d(padded, torch.ones(1, 1, kernel), stride=stride)
    assert out.shape[-1] == -(-length // stride)


def test_pmnet_table_1_lengths() -> None:
    """60 frames → 30 → 15 → 8 → 4 → 1, as in PMnet's Table 1."""
    disc = PMnetDiscriminator().eval()
    lengths: list[int] = []
    for conv in [*disc.convs, disc.out]:
        conv.register_forward_hook(lambda _m, _i, out: lengths.append(out.shape[-1]))
    logits = disc(torch.randn(5, 60, 3))
    assert lengths == [30, 15, 8, 4, 1]
    assert logits.shape == (5,)
    assert [c.out_channels for c in disc.convs] == [16, 32, 64, 128]


def test_nkn_inputs_are_deltas_velocities_and_skeleton(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    src, _ = skeleton_pair
    quats, root = motion(2, 20)
    feats = compute_features(quats, root, src)
    x = NKNDiscriminator.inputs(feats, src)
    assert x.shape == (2, 6 * 22 + 4, 19)
    torch.testing.assert_close(x[:, :66, 3], feats.pose_flat[:, 4] - feats.pose_flat[:, 3])
    torch.testing.assert_close(x[:, 66:70, 3], feats.root_vel[:, 3])
    torch.testing.assert_close(x[:, 70:, 3], src.flatten(-2))
    disc = NKNDiscriminator(channels=(8, 8, 8, 8))
    assert disc(x).shape == (2,)


@pytest.mark.parametrize("frames", [8, 60, 120])
def test_any_window_length_gives_one_logit(frames: int) -> None:
    disc = NKNDiscriminator(channels=(4, 4, 4, 4)).eval()
    assert disc(torch.randn(3, 6 * 22 + 4, frames)).shape == (3,)
