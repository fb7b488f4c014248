"""Residual retargeter specifics: starts as copy-scaled, causal denoiser, copied turning."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
import torch

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import compute_features
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.foot_lock import LEGS
from robot_retarget.nn.models.registry import build_model
from robot_retarget.nn.models.residual import CausalRotationDenoiser, ResidualRetargeter

Motion = Callable[..., tuple[torch.Tensor, torch.Tensor]]


@pytest.mark.parametrize("foot_lock", [False, True])
def test_untrained_model_is_copy_scaled(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor], foot_lock: bool
) -> None:
    """Untrained, the model is copy-scaled; its foot lock then turns only the legs."""
    model = build_model("residual", hidden_size=16, num_layers=2, foot_lock=foot_lock).eval()
    baseline = build_model("copy-scaled")
    src, tgt = skeleton_pair
    quats, root = motion(2, 15)
    with torch.no_grad():
        ours = model(quats, root, src, tgt)
        copy = baseline(quats, root, src, tgt)
    torch.testing.assert_close(ours.root_pos, copy.root_pos, atol=1e-5, rtol=0)
    angle = qt.angle_between(ours.local_quats, copy.local_quats)
    legs = [j for leg in LEGS for j in leg]
    others = [j for j in range(angle.shape[-1]) if j not in legs]
    assert float(angle[..., others].max()) < 1e-3
    if not foot_lock:
        assert float(angle.max()) < 1e-3


def test_checkpoints_from_before_the_foot_lock_load_without_it() -> None:
    config = ResidualRetargeter(hidden_size=16, num_layers=2).config()
    del config["foot_lock"]
    upgraded = ResidualRetargeter.upgrade_config(config)
    assert upgraded["foot_lock"] is False
    assert ResidualRetargeter(**upgraded).lock is None


def _denoiser_with_weights(weights: list[float]) -> CausalRotationDenoiser:
    """A denoiser whose filter weights are constants (last layer: zero weights, bias w)."""
    den = CausalRotationDenoiser(22, history=len(weights), hidden=8)
    last = den.net[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():
        last.weight.zero_()
        last.bias.copy_(torch.tensor(weights))
    return den


def test_zero_weights_pass_the_input_through(motion: Motion) -> None:
    quats, _ = motion(2, 10)
    with torch.no_grad():
        out = _denoiser_with_weights([0.0, 0.0, 0.0])(quats)
    assert float(qt.angle_between(out, quats).max()) < 1e-5


def test_unit_first_weight_holds_the_previous_frame(motion: Motion) -> None:
    """w = (1, 0, …): every non-root joint shows the previous frame's rotation, the root its
    own: what the filter learns to do for a dropped joint."""
    quats, _ = motion(2, 10)
    with torch.no_grad():
        out = _denoiser_with_weights([1.0, 0.0, 0.0])(quats)
    held = qt.angle_between(out[:, 1:, 1:], quats[:, :-1, 1:])
    assert float(held.max()) < 1e-4
    assert float(qt.angle_between(out[:, :, 0], quats[:, :, 0]).max()) < 1e-6


def test_step_equals_clip_denoiser(motion: Motion) -> None:
    torch.manual_seed(3)
    den = CausalRotationDenoiser(22, history=3, hidden=8)
    for p in den.parameters():
        torch.nn.init.normal_(p, 0.0, 0.3)
    quats, _ = motion(2, 9)
    with torch.no_grad():
        clip = den(quats)
        den.reset()
        frames = torch.stack([den.step(quats[:, t]) for t in range(9)], dim=1)
    torch.testing.assert_close(frames, clip, atol=1e-5, rtol=0)


def test_turning_rate_is_the_sources(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model("residual").eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 12)
    feats = compute_features(quats, root, src)
    with torch.no_grad():
        pred = model.retarget(feats, src, tgt)
    torch.testing.assert_close(pred.root_vel[..., 3], feats.root_vel[..., 3])


def test_correction_depends_on_proportions_not_size(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """A target scaled by k gets the same rotations and k times the root displacement."""
    model = tiny_model("residual").eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 12)
    with torch.no_grad():
        small = model(quats, root, src, tgt)
        large = model(quats, root, src, tgt * 3.0)
    assert float(qt.angle_between(small.local_quats, large.local_quats).max()) < 1e-3
    torch.testing.assert_close(
        large.root_pos - large.root_pos[:, :1],
        3.0 * (small.root_pos - small.root_pos[:, :1]),
        atol=1e-4,
        rtol=1e-4,
    )


def test_online_cache_follows_new_weights_after_training(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """Per-skeleton terms cached in eval mode are dropped when the model trains again."""
    model = tiny_model("residual")
    assert isinstance(model, ResidualRetargeter)
    src, tgt = skeleton_pair
    quats, root = motion(2, 6)
    model.eval()
    with torch.no_grad():
        before = model(quats, root, src, tgt).local_quats
        model.train()
        model.to_delta.bias.add_(0.5)
        model.eval()
        after = model(quats, root, src, tgt).local_quats
    assert float(qt.angle_between(before, after).max()) > 1e-2


def test_correction_is_bounded_for_any_input(
    motion: Motion, skeleton_pair: tuple[torch.Tensor, torch.Tensor]
) -> None:
    """However wild the input and the weights, Δq turns no joint by more than √3 × the cap."""
    model = build_model("residual", hidden_size=16, num_layers=2, max_correction_deg=20.0)
    with torch.no_grad():
        for param in model.parameters():
            param.normal_(0.0, 50.0)  # saturates every unit
    model.eval()
    src, tgt = skeleton_pair
    g = torch.Generator().manual_seed(1)
    quats = qt.from_rotation_vector(3.0 * torch.randn(2, 10, 22, 3, generator=g))
    _, root = motion(2, 10)
    feats = compute_features(quats, root, src)
    with torch.no_grad():
        pred = model.retarget(feats, src, tgt)
    turned = qt.angle_between(pred.extras["q_denoised"], pred.local_quats)
    assert torch.isfinite(turned).all()
    assert float(turned.max()) <= math.radians(20.0) * math.sqrt(3.0) + 1e-5


def test_cached_skeleton_terms_follow_new_weights_dtype_and_device(
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model("residual").eval()
    other = tiny_model("residual")
    with torch.no_grad():
        for param in other.parameters():
            param.add_(0.3)
    src, tgt = skeleton_pair
    quats, root = motion(2, 6)
    with torch.no_grad():
        before = model(quats, root, src, tgt).local_quats
        model.load_state_dict(other.state_dict())
        after = model(quats, root, src, tgt).local_quats
        assert float(qt.angle_between(before, after).max()) > 1e-2
        doubled = model.double()(quats.double(), root.double(), src.double(), tgt.double())
    assert doubled.local_quats.dtype == torch.float64


def test_standardizer_floor() -> None:
    from robot_retarget.nn.models.normalization import Standardizer

    norm = Standardizer(2, min_std=0.05)
    norm.fit(torch.tensor([[0.0, 1.0], [0.001, 3.0]]))
    torch.testing.assert_close(norm.std, torch.tensor([0.05, 1.0]))


def test_root_filter_keeps_gain_and_has_no_lag() -> None:
    """Any parameters: unit gain (no drift) and zero first moment (a steady walk is passed
    through unchanged, no lag)."""
    from robot_retarget.nn.models.residual import CausalVelocityFilter

    filt = CausalVelocityFilter(5)
    with torch.no_grad():
        filt.b.normal_(0.0, 1.0)
    a = filt.weights().detach()
    assert float(a.sum()) == pytest.approx(1.0, abs=1e-6)
    assert float((torch.arange(5.0) * a).sum()) == pytest.approx(0.0, abs=1e-5)
    ramp = torch.linspace(0.0, 1.0, 20)[None, :, None].repeat(2, 1, 3)  # accelerating root
    steady = torch.full((1, 20, 3), 0.04)
    with torch.no_grad():
        out = filt(steady)
        torch.testing.assert_close(out[:, 4:], steady[:, 4:])
        ramp_out = filt(ramp)
    torch.testing.assert_close(ramp_out[:, 4:], ramp[:, 4:], atol=1e-5, rtol=0)
