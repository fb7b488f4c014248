"""Training the 2D keypoint model: batches are reproducible and carry the camera's heading in
the root target; a few steps of train --model agnostic2d write checkpoints that load, with a
runtime equal to the torch model."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from robot_retarget.cli import train_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.synthetic import CLEAN
from robot_retarget.keypoints.virtual_camera import VirtualCamera, heading_quat
from robot_retarget.nn.agnostic2d_training import (
    TwoViewSampler,
    load_keypoint_checkpoint,
    render_window,
    rendered_batches,
)
from robot_retarget.nn.dataset import DatasetError, load_dataset
from robot_retarget.nn.models.agnostic2d import rotation_6d_to_matrix
from robot_retarget.runtime.agnostic2d import load_agnostic2d

TIME_LIMIT_S = 300


@pytest.mark.data
def test_batches_are_reproducible_and_targets_turn_with_the_camera(
    shared_data_dir: Path,
) -> None:
    data = load_dataset(shared_data_dir / "mocap", max_frames=240)
    train, _val = data.split()
    sampler = TwoViewSampler(train, window_frames=32, batch_size=3, seed=5)
    a, b = sampler.sample(7), sampler.sample(7)
    assert torch.equal(a.features, b.features)
    assert a.features.shape == (6, 32, 51)
    assert not torch.equal(a.features, sampler.sample(8).features)
    clip = train.clips[0]
    cam = VirtualCamera(1.2, 0.3, 4.0, 1000.0)
    _px, _v, target = render_window(clip, 0, 10, clip.offsets, cam, np.random.default_rng(0), CLEAN)
    expect = quat.mul(heading_quat(1.2), clip.local_quats[:10, 0])
    np.testing.assert_allclose(np.abs((target[:, 0] * expect).sum(-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(target[:, 1:], clip.local_quats[:10, 1:])


@pytest.mark.data
def test_loader_processes_render_the_same_batches_in_order(shared_data_dir: Path) -> None:
    train, _val = load_dataset(shared_data_dir / "mocap", max_frames=240).split()
    sampler = TwoViewSampler(train, window_frames=32, batch_size=2, seed=3)
    with rendered_batches(sampler, range(1, 6), 0) as inline:
        expected = list(inline)
    with rendered_batches(sampler, range(1, 6), 2) as ahead:
        got = list(ahead)
    assert len(got) == 5
    for e, g in zip(expected, got, strict=True):
        assert torch.equal(e.features, g.features)
        assert torch.equal(e.targets, g.targets)


def _tiny_run(data: Path, out: Path, *extra: str) -> argparse.ArgumentParser:
    """Train a tiny keypoint model for 4 steps into ``out``; the parser for further runs."""
    parser = argparse.ArgumentParser()
    train_cmd.configure(parser)
    args = parser.parse_args(
        ["--model", "agnostic2d", "--data", str(data / "mocap"), "--out", str(out),
         "--steps", "4", "--batch-size", "2", "--window", "32", "--val-every", "2",
         "--max-frames", "240", "--quiet", "--model-config", "channels=16",
         "--model-config", "static_hidden=8", "--model-config", "head_hidden=16", *extra]
    )  # fmt: skip
    assert train_cmd.run(args) == 0
    return parser


@pytest.mark.data
def test_train_command_writes_loadable_checkpoints(shared_data_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    extra = ("--loss-weight", "limb=2", "--loader-workers", "1")
    parser = _tiny_run(shared_data_dir, out, *extra)
    model, payload = load_keypoint_checkpoint(out / "best.pt")
    assert payload["metadata"]["validation_subjects"] == ["06", "08", "12"]
    assert json.loads((out / "config.json").read_text())["limb_weight"] == 2.0
    runtime = load_agnostic2d(out / "best.npz")
    x = torch.randn(1, 20, 51)
    with torch.no_grad():
        ref = quat.from_matrix(rotation_6d_to_matrix(model(x, True)[0])[0].double().numpy())
    got = runtime.run_features(x[0].double().numpy(), causal=True)
    assert np.abs(np.abs((ref * got).sum(-1)) - 1.0).max() < 1e-5
    with pytest.raises(train_cmd.TrainArgumentError, match="triplet, direction and limb"):
        train_cmd.run(parser.parse_args(["--model", "agnostic2d", "--out", str(out),
                                         "--loss-weight", "bone=1"]))  # fmt: skip


@pytest.mark.data
def test_a_centred_model_trains_on_whole_windows_and_is_chosen_by_them(
    shared_data_dir: Path, tmp_path: Path
) -> None:
    """``--model-config centered=true``: never run causally (that would raise), validated and
    chosen by the whole-window error alone; its runtime looks ahead."""
    out = tmp_path / "run"
    _tiny_run(shared_data_dir, out, "--model-config", "centered=true")
    model, payload = load_keypoint_checkpoint(out / "best.pt")
    assert model.centered
    assert set(payload["metadata"]["validation"]) == {"direction_error_deg_clip"}
    assert load_agnostic2d(out / "best.npz").centered


@pytest.mark.data
def test_excluded_subjects_are_left_out_and_unused_options_refused(
    shared_data_dir: Path, tmp_path: Path
) -> None:
    """``--exclude-subjects`` drops a held-out fold from training and validation alike (it was
    once ignored here: fold models trained on the subjects they were meant to leave out);
    options only the other models read are refused, not dropped silently."""
    out = tmp_path / "run"
    parser = _tiny_run(
        shared_data_dir, out, "--val-subjects", "13", "--exclude-subjects", "06,08,12"
    )
    _model, payload = load_keypoint_checkpoint(out / "best.pt")
    meta = payload["metadata"]
    assert meta["validation_subjects"] == ["13"]
    assert meta["excluded_subjects"] == ["06", "08", "12"]
    assert not {"06", "08", "12", "13"} & set(meta["train_subjects"])
    assert json.loads((out / "config.json").read_text())["exclude_subjects"] == ["06", "08", "12"]
    base = ["--model", "agnostic2d", "--data", str(shared_data_dir / "mocap"), "--out"]
    with pytest.raises(DatasetError, match=r"excluded subject\(s\) \['99'\]"):
        train_cmd.run(parser.parse_args([*base, str(tmp_path / "x"), "--exclude-subjects", "99"]))
    for option, value in (("--live-noise", "0.5"), ("--robots", "op3"), ("--log-every", "5")):
        with pytest.raises(train_cmd.TrainArgumentError, match=f"{option}: only the other"):
            train_cmd.run(parser.parse_args([*base, str(tmp_path / "y"), option, value]))


@pytest.mark.data
def test_a_run_fine_tunes_from_a_checkpoint_with_its_architecture(
    shared_data_dir: Path, tmp_path: Path
) -> None:
    """``--init-from``: the second run starts from the first's weights (its first validation
    is the first run's last, not a fresh model's), takes its architecture, records where it
    started, and refuses a ``--model-config`` that disagrees; ``--causal-probability 1`` runs
    every batch as ``stream`` does and is refused for a centred model and for other models."""
    first = tmp_path / "first"
    parser = _tiny_run(shared_data_dir, first)
    start = first / "last.pt"
    second = tmp_path / "second"
    base = ["--model", "agnostic2d", "--data", str(shared_data_dir / "mocap"), "--quiet",
            "--steps", "1", "--batch-size", "2", "--window", "32", "--val-every", "1",
            "--max-frames", "240"]  # fmt: skip
    args = parser.parse_args([*base, "--out", str(second), "--lr", "1e-12", "--init-from",
                              str(start), "--causal-probability", "1"])  # fmt: skip
    assert train_cmd.run(args) == 0
    tuned, payload = load_keypoint_checkpoint(second / "last.pt")
    original, first_payload = load_keypoint_checkpoint(start)
    assert tuned.config() == original.config()
    assert payload["metadata"]["init_from"] == str(start)
    assert json.loads((second / "config.json").read_text())["causal_probability"] == 1.0
    # A learning rate of 1e-12 leaves the weights where they started (AMSGrad's first step is
    # about lr in size), so the validation is the first run's.
    ours = payload["metadata"]["validation"]["direction_error_deg_causal"]
    theirs = first_payload["metadata"]["validation"]["direction_error_deg_causal"]
    assert ours == pytest.approx(theirs, abs=1e-3)
    with pytest.raises(RetargetError, match="channels=16, not channels=32"):
        train_cmd.run(parser.parse_args([*base, "--out", str(tmp_path / "x"), "--init-from",
                                         str(start), "--model-config", "channels=32"]))  # fmt: skip
    assert not (tmp_path / "x").exists()  # refused before any file (or its folder) is written
    with pytest.raises(RetargetError, match=r"numpy runtime.*pass its torch checkpoint"):
        train_cmd.run(parser.parse_args([*base, "--out", str(tmp_path / "v"), "--init-from",
                                         str(first / "last.npz")]))  # fmt: skip
    centred = ["--model-config", "centered=true", "--causal-probability", "0.5"]
    with pytest.raises(RetargetError, match="a centred model looks ahead"):
        train_cmd.run(parser.parse_args([*base, "--out", str(tmp_path / "y"), *centred]))
    with pytest.raises(RetargetError, match=r"--causal-probability 1.5 is not in \[0, 1\]"):
        train_cmd.run(parser.parse_args([*base, "--out", str(tmp_path / "z"),
                                         "--causal-probability", "1.5"]))  # fmt: skip
    with pytest.raises(train_cmd.TrainArgumentError, match="agnostic2d's"):
        train_cmd.run(parser.parse_args(["--model", "residual", "--out", str(tmp_path / "w"),
                                         "--init-from", str(start)]))  # fmt: skip
