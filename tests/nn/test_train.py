"""Training loop: run folder contents, reproducible resume, validation, refusals."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import pytest
import torch

from robot_retarget.nn.checkpoint import load_checkpoint
from robot_retarget.nn.dataset import WindowSampler, load_dataset
from robot_retarget.nn.models.registry import build_model
from robot_retarget.nn.train import (
    TrainConfig,
    TrainError,
    TrainProgress,
    same_skeleton_step,
    train,
    validate,
)

TINY_MODEL = {
    "nkn": {"hidden_size": 16, "num_layers": 1},
    "pmnet": {"hidden_size": 16, "num_layers": 2, "movement_channels": 8},
    "residual": {"hidden_size": 16, "num_layers": 2, "denoiser_hidden": 8},
}
TINY_DISC = {
    "nkn": {"channels": [4, 4, 4, 4]},
    "pmnet": {"channels": [4, 4, 4, 4]},
    "residual": {},
}


def _config(
    mocap_dir: Path, out: Path, cache: Path, model: str = "pmnet", steps: int = 3
) -> TrainConfig:
    return TrainConfig(
        model=model,
        data_dir=str(mocap_dir),
        out_dir=str(out),
        steps=steps,
        batch_size=4,
        window_frames=8,
        validation_subjects=("s2",),
        robots=("op3",),
        val_every=2,
        val_batches=1,
        checkpoint_every=2,
        log_every=1,
        model_config=TINY_MODEL[model],
        discriminator_config=TINY_DISC[model],
        cache_dir=str(cache),
        lr=1e-3,
    )


def test_run_folder_holds_checkpoints_and_logs(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    seen: list[TrainProgress] = []
    cfg = _config(mocap_dir, tmp_path / "run", cache_dir)
    result = train(cfg, progress=seen.append, command="python launch.py train ...")
    out = tmp_path / "run"
    for name in ("config.json", "last.pt", "best.pt", "trainer_state.pt", "log.csv"):
        assert (out / name).is_file(), name
    assert list(out.glob("events.out.tfevents.*"))
    assert result.steps == 3
    assert [p.step for p in seen] == [1, 2, 3]
    assert seen[1].validation is not None
    assert "score" in seen[1].validation
    ckpt = load_checkpoint(result.last_path, expected_data_hash=result.data_hash)
    assert ckpt.metadata["step"] == 3
    assert ckpt.metadata["validation_subjects"] == ["s2"]
    assert ckpt.metadata["train_config"]["model_config"] == TINY_MODEL["pmnet"]
    assert {"subject:s1", "subject:s3", "robot:op3"} <= set(ckpt.skeletons)
    assert "subject:s2" not in ckpt.skeletons
    rows = list(csv.DictReader((out / "log.csv").open()))
    assert {r["split"] for r in rows} == {"train", "val"}
    assert {"total", "reconstruction"} <= {r["metric"] for r in rows if r["split"] == "train"}
    saved = json.loads((out / "config.json").read_text())
    assert saved["data_hash"] == result.data_hash


def test_resume_continues_exactly_like_an_uninterrupted_run(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    straight = train(_config(mocap_dir, tmp_path / "a", cache_dir, steps=4))
    cfg = _config(mocap_dir, tmp_path / "b", cache_dir, steps=2)
    train(cfg)
    resumed = train(dataclasses.replace(cfg, steps=4), resume=True)
    assert resumed.steps == 4
    a = load_checkpoint(straight.last_path).model.state_dict()
    b = load_checkpoint(resumed.last_path).model.state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=1e-6, msg=key)


def test_nkn_trains_with_real_target_motion(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    result = train(_config(mocap_dir, tmp_path / "nkn", cache_dir, model="nkn", steps=2))
    assert load_checkpoint(result.best_path).model.name == "nkn"


def test_residual_trains_without_a_discriminator_and_resumes_exactly(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    straight = train(_config(mocap_dir, tmp_path / "a", cache_dir, model="residual", steps=4))
    assert load_checkpoint(straight.best_path).model.name == "residual"
    rows = list(csv.DictReader((tmp_path / "a" / "log.csv").open()))
    assert {"effector", "denoise", "consistency"} <= {r["metric"] for r in rows}
    cfg = _config(mocap_dir, tmp_path / "b", cache_dir, model="residual", steps=2)
    train(cfg)
    resumed = train(dataclasses.replace(cfg, steps=4), resume=True)
    a = load_checkpoint(straight.last_path).model.state_dict()
    b = load_checkpoint(resumed.last_path).model.state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=1e-6, msg=key)


def test_loss_weight_overrides_change_training_and_unknown_ones_are_refused(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    cfg = _config(mocap_dir, tmp_path / "a", cache_dir, model="residual", steps=2)
    plain = train(cfg)
    heavy = train(
        dataclasses.replace(cfg, out_dir=str(tmp_path / "b"), loss_weights={"bone": 50.0})
    )
    a = load_checkpoint(plain.last_path).model.state_dict()
    b = load_checkpoint(heavy.last_path).model.state_dict()
    assert any(not torch.equal(a[k], b[k]) for k in a)
    with pytest.raises(TrainError, match=r"unknown loss weight.*'bogus'.*allowed: effector"):
        train(dataclasses.replace(cfg, out_dir=str(tmp_path / "c"), loss_weights={"bogus": 1.0}))
    assert not (tmp_path / "c").exists()
    for bad in (float("nan"), -1.0, "heavy"):
        with pytest.raises(TrainError, match="finite numbers"):
            train(dataclasses.replace(cfg, out_dir=str(tmp_path / "d"), loss_weights={"bone": bad}))


def test_refuses_to_overwrite_untrainable_models_and_bad_resume(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    cfg = _config(mocap_dir, tmp_path / "run", cache_dir, steps=1)
    train(cfg)
    with pytest.raises(TrainError, match="pass --resume"):
        train(cfg)
    with pytest.raises(TrainError, match="cannot resume"):
        train(dataclasses.replace(cfg, model="nkn", model_config={}), resume=True)
    with pytest.raises(TrainError, match="nothing to resume"):
        train(dataclasses.replace(cfg, out_dir=str(tmp_path / "empty")), resume=True)
    with pytest.raises(TrainError, match="cannot be trained"):
        train(dataclasses.replace(cfg, model="copy"))


def test_excluded_subjects_are_neither_trained_nor_validated_on(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    cfg = _config(mocap_dir, tmp_path / "run", cache_dir, model="residual", steps=2)
    result = train(dataclasses.replace(cfg, exclude_subjects=("s3",)))
    for path in (result.last_path, result.best_path):
        ckpt = load_checkpoint(path)
        assert ckpt.metadata["train_subjects"] == ["s1"]
        assert ckpt.metadata["validation_subjects"] == ["s2"]
        assert "subject:s3" not in ckpt.skeletons
    stored = json.loads((tmp_path / "run" / "config.json").read_text())
    assert stored["config"]["exclude_subjects"] == ["s3"]
    assert TrainConfig.from_json(stored["config"]).exclude_subjects == ("s3",)
    # The hash names the data actually used: resuming on the whole folder is refused.
    with pytest.raises(TrainError, match="cannot resume"):
        train(dataclasses.replace(cfg, steps=3), resume=True)
    with pytest.raises(TrainError, match=r"excluded subject\(s\) \['s9'\] are not in the data"):
        train(dataclasses.replace(cfg, out_dir=str(tmp_path / "x"), exclude_subjects=("s9",)))


def test_no_validation_subjects_means_no_validation_and_best_is_last(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    seen: list[TrainProgress] = []
    cfg = _config(mocap_dir, tmp_path / "run", cache_dir, model="residual", steps=3)
    cfg = dataclasses.replace(cfg, validation_subjects=(), exclude_subjects=("s3",))
    result = train(cfg, progress=seen.append)
    assert all(p.validation is None for p in seen)
    assert seen[-1].step == 3
    rows = list(csv.DictReader((tmp_path / "run" / "log.csv").open()))
    assert rows
    assert {r["split"] for r in rows} == {"train"}
    best, last = load_checkpoint(result.best_path), load_checkpoint(result.last_path)
    assert best.metadata["step"] == last.metadata["step"] == 3
    assert best.metadata["train_subjects"] == ["s1", "s2"]
    assert best.metadata["validation_subjects"] == []
    for key, value in last.model.state_dict().items():
        torch.testing.assert_close(best.model.state_dict()[key], value, rtol=0, atol=0)


def test_validation_of_copy_is_exact_on_same_skeleton(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    batch = WindowSampler(data, window_frames=8, batch_size=4).sample(0)
    metrics = validate(build_model("copy"), [batch])
    assert metrics["recon"] == pytest.approx(0.0, abs=1e-9)
    assert metrics["cycle"] == pytest.approx(0.0, abs=1e-9)
    # Copy keeps the heading: the score is the effector, contact and bone-direction error.
    expected = metrics["ee"] + metrics["contact"] + math.radians(metrics["bone_deg"])
    assert metrics["score"] == pytest.approx(expected)


def test_same_skeleton_reconstruction_option(
    mocap_dir: Path, tmp_path: Path, cache_dir: Path
) -> None:
    seen: list[TrainProgress] = []
    cfg = dataclasses.replace(
        _config(mocap_dir, tmp_path / "run", cache_dir, steps=2), same_skeleton_recon=1.0
    )
    train(cfg, progress=seen.append)
    assert all("same_recon" in p.losses for p in seen)
    assert all(p.losses["same_recon"] >= 0.0 for p in seen)
    saved = load_checkpoint(tmp_path / "run" / "last.pt").metadata["train_config"]
    assert saved["same_skeleton_recon"] == 1.0


def test_same_skeleton_step_lowers_the_same_skeleton_error(
    mocap_dir: Path, cache_dir: Path
) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    batch = WindowSampler(data, window_frames=8, batch_size=8, seed=1).sample(0)
    torch.manual_seed(0)
    model = build_model("pmnet", dropout=0.0, **TINY_MODEL["pmnet"])
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
    losses = [same_skeleton_step(model, batch, optimizer, 1.0) for _ in range(30)]
    assert losses[-1] < 0.5 * losses[0]
