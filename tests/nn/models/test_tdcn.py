"""TDCN: the stated receptive fields (81 frames back when causal, 40 each way when centred),
the patch discriminator's 31-frame patches, and the height loss."""

from __future__ import annotations

import pytest
import torch

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import compute_features
from robot_retarget.nn.models.registry import build_model
from robot_retarget.nn.models.tdcn import TDCN
from robot_retarget.nn.models.tdcn_training import height_loss
from robot_retarget.nn.patch_discriminator import PatchDiscriminator, patch_inputs
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from tests.nn.models.conftest import offsets_of, random_motion

FRAMES = 130


def _pose_after_nudging(model: TDCN, frame: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Heading-free output rotations (T, J, 4) of a clip, and of the same clip with one
    elbow rotation changed at ``frame`` (a change no other frame's features see)."""
    quats, root = random_motion(1, FRAMES, seed=4)
    offsets = offsets_of(default_canonical_skeleton(), 1)
    nudged = quats.clone()
    nudged[0, frame, 8] = qt.normalize(nudged[0, frame, 8] + torch.tensor([0.0, 0.3, 0.2, 0.0]))
    with torch.no_grad():
        a = model(quats, root, offsets, 0.5 * offsets).features.local_quats[0]
        b = model(nudged, root, offsets, 0.5 * offsets).features.local_quats[0]
    return a, b


def _changed(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Per frame: did any output rotation move (beyond float rounding)?"""
    return (a - b).abs().amax(dim=(-1, -2)) > 1e-7


def _tdcn(causal: bool) -> TDCN:
    torch.manual_seed(0)
    model = build_model("tdcn", channels=16, causal=causal)
    assert isinstance(model, TDCN)
    with torch.no_grad():  # the head starts near the identity: make every frame's share show
        model.head.weight.normal_(0.0, 0.5)
    return model.eval()


def test_causal_frames_see_the_last_81_frames_only() -> None:
    model = _tdcn(causal=True)
    assert model.receptive_field == 81
    changed = _changed(*_pose_after_nudging(model, 20))
    assert not changed[:20].any()  # the past does not see the future
    assert changed[20:101].all()  # frames 20 … 100 see frame 20
    assert not changed[101:].any()  # frame 101 sees frames 21 … 101


def test_centred_frames_see_40_frames_each_way() -> None:
    model = _tdcn(causal=False)
    changed = _changed(*_pose_after_nudging(model, 60))
    assert not changed[:20].any()
    assert changed[20:101].all()
    assert not changed[101:].any()
    model.reset()
    quats, root = random_motion(1, 1)
    offsets = offsets_of(default_canonical_skeleton(), 1)
    with pytest.raises(ModelLoadError, match="non-causal"):
        model.step(quats[:, 0], root[:, 0], offsets, offsets)


def test_patch_discriminator_scores_each_31_frame_patch() -> None:
    disc = PatchDiscriminator(channels=8)
    assert disc.receptive_field == 31
    quats, root = random_motion(2, 40)
    offsets = offsets_of(default_canonical_skeleton(), 2)
    feats = compute_features(quats, root, offsets)
    x = patch_inputs(feats.local_pos, feats.root_vel, offsets)
    assert x.shape == (2, 2 * 22 + 1, 39)
    assert disc(x).shape == (2, 39 - 30)
    with pytest.raises(ValueError, match="at least 31"):
        disc(x[..., :30])


def test_height_loss_is_zero_for_the_same_motion_at_any_size() -> None:
    """Displacements over the height: a motion and its uniformly scaled copy agree; a
    motion and a different one do not."""
    quats, root = random_motion(2, 30, seed=1)
    offsets = offsets_of(default_canonical_skeleton(), 2)
    h = torch.full((2,), 1.0)
    a = compute_features(quats, root, offsets)
    small = compute_features(quats, 0.4 * root, 0.4 * offsets)
    assert torch.allclose(height_loss(a, h, small, 0.4 * h, 5.0), torch.zeros(2), atol=1e-9)
    other_q, other_root = random_motion(2, 30, seed=2)
    b = compute_features(other_q, other_root, offsets)
    assert (height_loss(a, h, b, h, 5.0) > 1e-4).all()


def test_metric_losses_join_the_paper_objective_only_when_weighted() -> None:
    from robot_retarget.nn.models.optimizers import make_optimizers
    from robot_retarget.nn.models.registry import build_discriminator
    from robot_retarget.nn.models.training import training_step
    from tests.nn.models.conftest import make_batch

    batch = make_batch(frames=40)
    for weights, extra in (({}, set()), ({"bone": 3.0, "denoise": 3.0}, {"bone", "denoise"})):
        torch.manual_seed(0)
        model = build_model("tdcn", channels=8, blocks=2)
        disc = build_discriminator("tdcn", channels=8, dilations=(1, 2))
        losses = training_step(model, disc, batch, make_optimizers(model, disc), weights=weights)
        assert extra <= set(losses)
        assert not ({"effector", "contact", "skate", "bone", "denoise"} - extra) & set(losses)
        assert all(torch.isfinite(torch.tensor(v)) for v in losses.values())
