"""Training steps: real paper losses, deterministic, and they reduce the loss."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import torch

from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.nn.models.optimizers import make_optimizers
from robot_retarget.nn.models.training import (
    NKNLossWeights,
    nkn_training_step,
    training_step,
)

Build = Callable[[str], RetargetModel]
BuildDisc = Callable[[str], torch.nn.Module]

EXPECTED_KEYS = {
    "nkn": {"total", "cycle", "square", "adversarial", "twist", "smoothing", "discriminator"},
    "pmnet": {"total", "reconstruction", "pose", "motion", "rotation", "discriminator"},
    "residual": {
        "total",
        "effector",
        "contact",
        "bone",
        "skate",
        "denoise",
        "consistency",
        "root",
        "rotation",
    },
    "tdcn": {
        "total",
        "cycle",
        "twist",
        "height",
        "square",
        "adversarial",
        "regularization",
        "orientation",
        "discriminator",
    },
    "san": {"total", "reconstruction", "ee_velocity", "latent", "adversarial", "discriminator"},
}
# The term each model learns first: NKN's cycle consistency, PMnet's pose reconstruction, the
# residual model's supervised denoising.
MAIN_TERM = {
    "nkn": "cycle",
    "pmnet": "reconstruction",
    "residual": "denoise",
    "tdcn": "cycle",
    "san": "reconstruction",
}


def _disc(name: str, build: BuildDisc) -> torch.nn.Module | None:
    return None if name == "residual" else build(name)


@pytest.mark.parametrize("name", ["nkn", "pmnet", "residual", "tdcn", "san"])
def test_a_few_steps_reduce_the_loss(
    name: str, tiny_model: Build, tiny_discriminator: BuildDisc, batch: RetargetBatch
) -> None:
    model = tiny_model(name)
    disc = _disc(name, tiny_discriminator)
    opt = make_optimizers(model, disc, lr=3e-3)
    # A fixed seed per step: the residual model's input corruption is the same every step.
    history = []
    for _ in range(12):
        torch.manual_seed(11)
        history.append(training_step(model, disc, batch, opt))
    assert EXPECTED_KEYS[name] <= set(history[0])
    assert all(torch.isfinite(torch.tensor(list(h.values()))).all() for h in history)
    main = MAIN_TERM[name]
    assert history[-1][main] < 0.8 * history[0][main]
    assert history[-1]["total"] < history[0]["total"]


@pytest.mark.parametrize("name", ["nkn", "pmnet", "residual", "tdcn", "san"])
def test_steps_are_deterministic(
    name: str, tiny_model: Build, tiny_discriminator: BuildDisc, batch: RetargetBatch
) -> None:
    runs = []
    for _ in range(2):
        model = tiny_model(name)
        disc = _disc(name, tiny_discriminator)
        opt = make_optimizers(model, disc)
        torch.manual_seed(5)
        runs.append([training_step(model, disc, batch, opt) for _ in range(2)])
    assert runs[0] == runs[1]


def test_nkn_uses_square_loss_only_where_target_is_source(
    tiny_model: Build, tiny_discriminator: BuildDisc, batch: RetargetBatch
) -> None:
    model = tiny_model("nkn")
    disc = tiny_discriminator("nkn")
    opt = make_optimizers(model, disc)
    all_same = RetargetBatch(
        src_local_quats=batch.src_local_quats,
        src_root_pos=batch.src_root_pos,
        src_offsets=batch.src_offsets,
        tgt_offsets=batch.src_offsets,
        same_skeleton=torch.ones(4, dtype=torch.bool),
        real_local_quats=batch.real_local_quats,
        real_root_pos=batch.real_root_pos,
    )
    before = [p.detach().clone() for p in disc.parameters()]
    losses = training_step(model, disc, all_same, opt)
    assert losses["adversarial"] == 0.0
    assert losses["square"] > 0.0
    assert "discriminator" not in losses  # nothing to discriminate: no update
    assert all(torch.equal(a, b) for a, b in zip(before, disc.parameters(), strict=True))


def test_nkn_discriminator_waits_while_it_wins(
    tiny_model: Build, tiny_discriminator: BuildDisc, batch: RetargetBatch
) -> None:
    """Appendix E balancing: no discriminator update while P(real | fake) < 0.3."""
    model = tiny_model("nkn")
    disc = tiny_discriminator("nkn")
    opt = make_optimizers(model, disc)
    with torch.no_grad():
        disc.out.bias.fill_(-20.0)  # the discriminator calls everything fake
    before = [p.detach().clone() for p in disc.parameters()]
    losses = nkn_training_step(model, disc, batch, opt, NKNLossWeights())
    assert losses["disc_fake_prob"] < 0.3
    assert losses["disc_updated"] == 0.0
    assert all(torch.equal(a, b) for a, b in zip(before, disc.parameters(), strict=True))
    # Without the balancing threshold it does update.
    nkn_training_step(model, disc, batch, opt, NKNLossWeights(disc_min_fake_prob=0.0))
    assert not all(torch.equal(a, b) for a, b in zip(before, disc.parameters(), strict=True))


def test_copy_models_have_no_training_step(
    tiny_model: Build, tiny_discriminator: BuildDisc, batch: RetargetBatch
) -> None:
    model = tiny_model("copy")
    disc = tiny_discriminator("pmnet")
    opt = make_optimizers(tiny_model("pmnet"), disc)
    with pytest.raises(ValueError, match="no training step"):
        training_step(model, disc, batch, opt)


def test_batch_rejects_inconsistent_shapes(batch: RetargetBatch) -> None:
    with pytest.raises(ValueError, match="tgt_offsets"):
        RetargetBatch(
            batch.src_local_quats,
            batch.src_root_pos,
            batch.src_offsets,
            batch.tgt_offsets[:2],
            batch.same_skeleton,
        )
    with pytest.raises(ValueError, match="both"):
        RetargetBatch(
            batch.src_local_quats,
            batch.src_root_pos,
            batch.src_offsets,
            batch.tgt_offsets,
            batch.same_skeleton,
            real_local_quats=batch.src_local_quats,
        )


def test_batch_moves_between_devices(batch: RetargetBatch) -> None:
    moved = batch.to("meta")
    assert moved.src_local_quats.device.type == "meta"
    assert moved.real_root_pos is not None
    assert moved.real_root_pos.device.type == "meta"
    assert batch.to("cpu").src_offsets.device.type == "cpu"


def test_live_noise_trains_the_residual_denoiser_only(
    tiny_model: Build, tiny_discriminator: BuildDisc, batch: RetargetBatch
) -> None:
    """``--live-noise``: the residual step corrupts a share of its denoising samples as a live
    position sender's (a different denoising loss, still finite); other models refuse it."""
    losses = []
    for share in (0.0, 1.0):
        model = tiny_model("residual")
        opt = make_optimizers(model, None)
        torch.manual_seed(2)
        losses.append(training_step(model, None, batch, opt, live_noise=share))
    assert all(torch.isfinite(torch.tensor(list(x.values()))).all() for x in losses)
    assert losses[0]["denoise"] != losses[1]["denoise"]
    assert losses[0]["effector"] == losses[1]["effector"]  # the clean pass is untouched
    model = tiny_model("pmnet")
    disc = tiny_discriminator("pmnet")
    with pytest.raises(ValueError, match="live-noise"):
        training_step(model, disc, batch, make_optimizers(model, disc), live_noise=0.5)
