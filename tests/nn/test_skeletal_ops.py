"""Skeletal convolution reads only its neighbourhood (and, causal, only the past); pooling
averages, unpooling copies; checkpoints with the dense kernel still load."""

from __future__ import annotations

import pytest
import torch

from robot_retarget.nn.skeletal_ops import SkeletalConv, SkeletalPool, SkeletalUnpool
from robot_retarget.skeleton.armatures import canonical_topology

TOPOLOGY = canonical_topology()
LEVEL = TOPOLOGY.base
C_IN, C_OUT, K, T = 3, 2, 3, 10


def _conv(causal: bool = True) -> SkeletalConv:
    torch.manual_seed(0)
    return SkeletalConv(
        LEVEL, [C_IN] * LEVEL.size, [C_OUT] * LEVEL.size, kernel_size=K, distance=2, causal=causal
    )


@pytest.mark.parametrize("armature", [0, 4, 13, 17])
def test_an_armature_reaches_exactly_its_neighbourhood(armature: int) -> None:
    conv = _conv()
    x = torch.randn(1, LEVEL.size, C_IN, T)
    bumped = x.clone()
    bumped[0, armature, :, 5] += 1.0
    with torch.no_grad():
        diff = (conv(bumped) - conv(x)).view(1, LEVEL.size, C_OUT, T).abs()
    touched = {a for a in range(LEVEL.size) if diff[0, a].amax() > 1e-6}
    near = {a for a in range(LEVEL.size) if armature in LEVEL.neighbours(2)[a]}
    assert touched == near
    # Causal: frames before the change do not see it; frames 5 … 5 + K − 1 do.
    assert diff[0, :, :, :5].amax() == 0.0
    assert diff[0, armature, :, 5 : 5 + K].amax(dim=0).gt(0).all()
    assert diff[0, :, :, 5 + K :].amax() == 0.0


def test_centred_kernels_see_both_ways() -> None:
    conv = _conv(causal=False)
    x = torch.randn(1, LEVEL.size, C_IN, T)
    bumped = x.clone()
    bumped[0, 3, :, 5] += 1.0
    with torch.no_grad():
        diff = (conv(bumped) - conv(x)).view(1, LEVEL.size, C_OUT, T)[0, 3].abs().amax(0)
    assert diff[4] > 0
    assert diff[6] > 0
    assert diff[3] == 0
    assert diff[7] == 0


def test_only_neighbourhood_weights_are_parameters() -> None:
    conv = _conv()
    dense = conv.dense_weight()
    assert conv.weight.numel() == int((dense != 0).sum())
    assert conv.weight.numel() < dense.numel() / 2


def test_a_dense_checkpoint_loads_into_the_compact_kernel() -> None:
    conv = _conv()
    state = {"weight": conv.dense_weight().detach().clone(), "bias": conv.bias.detach().clone()}
    state["mask"] = (state["weight"] != 0).float()
    other = _conv()
    with torch.no_grad():
        other.weight.zero_()
    other.load_state_dict(state)
    torch.testing.assert_close(other.weight, conv.weight)


def test_pool_averages_and_unpool_copies() -> None:
    groups = TOPOLOGY.pooling(2)[0]
    x = torch.randn(2, LEVEL.size, 4, T)
    pooled = SkeletalPool(groups, LEVEL.size)(x)
    assert pooled.shape == (2, len(groups), 4, T)
    for g, members in enumerate(groups):
        torch.testing.assert_close(pooled[:, g], x[:, list(members)].mean(1))
    back = SkeletalUnpool(groups, LEVEL.size)(pooled)
    for g, members in enumerate(groups):
        for a in members:
            torch.testing.assert_close(back[:, a], pooled[:, g])


def test_wrong_channel_lists_are_refused() -> None:
    with pytest.raises(ValueError, match="one entry per armature"):
        SkeletalConv(LEVEL, [1, 2], [1, 2], kernel_size=3)
