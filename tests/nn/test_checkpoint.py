"""Checkpoints: save → load gives identical outputs; bad files give ModelLoadError."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.checkpoint import (
    FORMAT,
    VERSION,
    fingerprint,
    load_checkpoint,
    save_checkpoint,
)
from robot_retarget.nn.features import compute_features
from robot_retarget.nn.models.registry import build_model
from robot_retarget.skeleton.canonical import default_canonical_skeleton

TINY = {
    "copy-scaled": {},
    "nkn": {"hidden_size": 12, "num_layers": 2},
    "pmnet": {"hidden_size": 12, "num_layers": 2, "movement_channels": 4},
    "residual": {"hidden_size": 12, "num_layers": 2, "denoiser_hidden": 6},
}


def _motion() -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(0)
    quats = qt.from_rotation_vector(0.3 * torch.randn(2, 7, 22, 3, generator=g))
    root = torch.cumsum(0.03 * torch.randn(2, 7, 3, generator=g), 1)
    src = torch.tensor(np.asarray(default_canonical_skeleton().offsets), dtype=torch.float32)
    src = src[None].repeat(2, 1, 1)
    return quats, root, src, src * 0.4


@pytest.mark.parametrize("name", sorted(TINY))
def test_round_trip_gives_identical_outputs(name: str, tmp_path: Path) -> None:
    torch.manual_seed(0)
    model = build_model(name, **TINY[name])
    with torch.no_grad():  # layers that start at zero (residual) must round-trip values too
        for param in model.parameters():
            if not param.any():
                param.normal_(0.0, 0.1)
    quats, root, src, tgt = _motion()
    model.fit_normalization(compute_features(quats, root, src), src)
    model.eval()
    skeletons = {"human": np.asarray(default_canonical_skeleton().offsets), "robot": tgt[0].numpy()}
    path = save_checkpoint(
        tmp_path / "sub" / "m.pt",
        model,
        skeletons=skeletons,
        data_hash="abc123",
        metadata={"steps": 3, "losses": [1.5, 0.5]},
    )
    loaded = load_checkpoint(path)
    assert not loaded.model.training
    assert loaded.model.config() == model.config()
    assert loaded.data_hash == "abc123"
    assert loaded.metadata == {"steps": 3, "losses": [1.5, 0.5]}
    assert set(loaded.skeletons) == {"human", "robot"}
    np.testing.assert_allclose(loaded.skeletons["robot"], skeletons["robot"])
    with torch.no_grad():
        a = model(quats, root, src, tgt)
        b = loaded.model(quats, root, src, tgt)
    assert torch.equal(a.local_quats, b.local_quats)
    assert torch.equal(a.root_pos, b.root_pos)
    assert not (tmp_path / "sub" / "m.pt.tmp").exists()


def _save_raw(path: Path, payload: object) -> Path:
    torch.save(payload, path)
    return path


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ModelLoadError, match="no such checkpoint") as info:
        load_checkpoint(tmp_path / "nope.pt")
    assert info.value.path == str(tmp_path / "nope.pt")


def test_garbage_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.pt"
    path.write_bytes(b"not a checkpoint at all")
    with pytest.raises(ModelLoadError, match="not a readable checkpoint"):
        load_checkpoint(path)


def test_foreign_torch_file(tmp_path: Path) -> None:
    path = _save_raw(tmp_path / "w.pt", {"weight": torch.zeros(3)})
    with pytest.raises(ModelLoadError, match="format"):
        load_checkpoint(path)


def test_newer_version(tmp_path: Path) -> None:
    path = _save_raw(tmp_path / "v.pt", {"format": FORMAT, "version": VERSION + 1})
    with pytest.raises(ModelLoadError, match="upgrade"):
        load_checkpoint(path)


def test_unknown_model(tmp_path: Path) -> None:
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "model": "no-such-model",
        "config": {},
        "state_dict": {},
    }
    with pytest.raises(ModelLoadError, match="unknown model 'no-such-model'") as info:
        load_checkpoint(_save_raw(tmp_path / "u.pt", payload))
    assert info.value.model == "no-such-model"


def test_weights_that_do_not_fit(tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path / "m.pt", build_model("nkn", hidden_size=8, num_layers=1))
    payload = torch.load(path, weights_only=True)
    payload["config"]["hidden_size"] = 9
    with pytest.raises(ModelLoadError, match="do not fit"):
        load_checkpoint(_save_raw(path, payload))


def test_expected_data_hash(tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path / "m.pt", build_model("copy"), data_hash="aaa")
    assert load_checkpoint(path, expected_data_hash="aaa").data_hash == "aaa"
    with pytest.raises(ModelLoadError, match="retrain"):
        load_checkpoint(path, expected_data_hash="bbb")


def test_fingerprint() -> None:
    a = np.arange(6.0).reshape(2, 3)
    assert fingerprint([a]) == fingerprint([a.copy()])
    assert fingerprint([a]) != fingerprint([a.reshape(3, 2)])
    b = a.copy()
    b[0, 0] = 1e-9
    assert fingerprint([a]) != fingerprint([b])
    assert fingerprint([a, a]) != fingerprint([a])
