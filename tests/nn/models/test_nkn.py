"""NKN specifics: FK layer, near-identity start, conditioning on the target skeleton."""

from __future__ import annotations

from collections.abc import Callable

import torch

from robot_retarget.nn.features import compute_features, local_positions
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.nkn import NKN

Motion = Callable[..., tuple[torch.Tensor, torch.Tensor]]


def test_fk_layer_output_is_fk_of_the_predicted_rotations(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model("nkn")
    src, tgt = skeleton_pair
    quats, root = motion(2, 6)
    pred = model.retarget(compute_features(quats, root, src), src, tgt)
    assert pred.local_pos is not None
    torch.testing.assert_close(pred.local_pos, local_positions(pred.local_quats, tgt))


def test_starts_near_identity_rotations(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """The paper initialises the quaternion outputs close to the identity."""
    model = tiny_model("nkn").eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 6)
    with torch.no_grad():
        out = model(quats, root, src, tgt)
    w = out.features.local_quats[..., 1:, 0].abs()
    assert float(w.min()) > 0.99


def test_decoder_is_conditioned_on_the_target_skeleton(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model("nkn").eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 6)
    with torch.no_grad():
        a = model(quats, root, src, tgt)
        b = model(quats, root, src, tgt * 1.5)
    assert not torch.allclose(a.features.local_quats, b.features.local_quats)


def test_paper_defaults() -> None:
    model = NKN()
    assert model.config() == {"hidden_size": 512, "num_layers": 2}
    assert model.encoder.num_layers == 2
    assert model.decoder.hidden_size == 512


def test_fit_normalization_standardises_the_encoder_input(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    model = NKN(hidden_size=8, num_layers=1)
    src, _ = skeleton_pair
    quats, root = motion(2, 30)
    feats = compute_features(quats, root, src)
    model.fit_normalization(feats, src)
    z = model.pose_norm(feats.pose_flat).flatten(0, 1)
    moving = feats.pose_flat.flatten(0, 1).std(dim=0) > 1e-3  # the root's entry never moves
    torch.testing.assert_close(z.mean(0)[moving], torch.zeros(int(moving.sum())), atol=1e-4, rtol=0)
    torch.testing.assert_close(
        z.std(0, unbiased=False)[moving], torch.ones(int(moving.sum())), atol=1e-3, rtol=0
    )
