"""Inference: loading models by name or path, clip and online paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from robot_retarget.errors import ModelLoadError
from robot_retarget.motion import HumanMotion
from robot_retarget.nn import inference
from robot_retarget.nn.benchmark import synthetic_motion
from robot_retarget.nn.checkpoint import save_checkpoint
from robot_retarget.nn.inference import (
    OnlineRetargeter,
    load_model,
    retarget_clip,
    retarget_motion,
)
from robot_retarget.nn.models.registry import build_model
from robot_retarget.skeleton.canonical import default_canonical_skeleton

TINY = {
    "nkn": {"hidden_size": 16, "num_layers": 1},
    "pmnet": {"hidden_size": 16, "num_layers": 2, "movement_channels": 8},
}


def _save_tiny(path: Path, name: str = "pmnet") -> Path:
    torch.manual_seed(0)
    model = build_model(name, **TINY[name])
    return save_checkpoint(path, model, skeletons={"human": np.zeros((22, 3))}, data_hash="abc")


def test_builtin_names_load_without_files() -> None:
    for name in inference.BUILTIN_MODELS:
        loaded = load_model(name)
        assert loaded.name == name
        assert loaded.architecture == name
        assert loaded.path is None


def test_unknown_name_lists_what_exists() -> None:
    with pytest.raises(ModelLoadError, match="available names: copy, copy-scaled") as info:
        load_model("no-such-model")
    assert info.value.model == "no-such-model"


def test_files_that_are_not_models_say_what_to_pass(tmp_path: Path) -> None:
    """eval and export read checkpoints: a clip or a trajectory given as a model says what it
    is and what to name instead (a runtime .npz is no answer here)."""
    from robot_retarget.motion.trajectory import RobotTrajectory

    clip = Path(__file__).resolve().parents[1] / "fixtures" / "motion" / "tiny_walk.bvh"
    trajectory = RobotTrajectory(("a",), np.zeros((2, 1)), 125.0).write(tmp_path / "t.npz")
    for path, kind in ((clip, "a BVH motion clip"), (trajectory, "a robot trajectory")):
        with pytest.raises(ModelLoadError, match=f"{kind}.*, not a model: name a model") as e:
            load_model(path)
        assert "a .pt checkpoint or a training run folder" in str(e.value)
        assert "Unpickling" not in str(e.value)
        assert "runtime file" not in str(e.value)
    with pytest.raises(ModelLoadError, match=r"\(or pass a \.pt path"):
        load_model("no-such-model")  # eval takes no runtime .npz: not offered


def test_checkpoint_by_path_by_run_folder_and_by_shipped_name(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _save_tiny(tmp_path / "run" / "best.pt")
    by_path = load_model(path)
    assert by_path.architecture == "pmnet"
    assert by_path.data_hash == "abc"
    assert not by_path.model.training
    assert load_model(tmp_path / "run").path == path  # a training run's folder
    shipped = tmp_path / "shipped"
    _save_tiny(shipped / "mine.pt")
    monkeypatch.setattr(inference, "CHECKPOINT_DIR", shipped)
    _save_tiny(shipped / "agnostic2d_clip.pt")  # a keypoint model lifts, it is no --model
    assert "mine" in inference.available_models()
    assert "agnostic2d_clip" not in inference.available_models()
    loaded = load_model("mine")
    assert loaded.name == "mine"
    assert loaded.architecture == "pmnet"


def test_default_model_name_is_a_shipped_checkpoint_or_a_clear_error() -> None:
    if inference.DEFAULT_MODEL in inference.shipped_checkpoints():
        assert load_model().name == inference.DEFAULT_MODEL
    else:
        with pytest.raises(ModelLoadError, match="no model 'default'"):
            load_model()


def test_copy_on_the_same_skeleton_reproduces_the_clip() -> None:
    q, root = synthetic_motion(20)
    offs = default_canonical_skeleton().offsets
    out_q, out_root = retarget_clip(load_model("copy"), q, root, offs, offs)
    np.testing.assert_allclose(np.abs(np.sum(out_q * q, axis=-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(out_root, root, atol=1e-9)


def test_retarget_motion_lands_on_the_target_skeleton() -> None:
    q, root = synthetic_motion(12)
    human = default_canonical_skeleton()
    motion = HumanMotion(human, q, root, 30.0)
    small = human.scaled(0.3)
    out = retarget_motion(load_model("copy-scaled"), motion, small)
    assert out.skeleton is small
    assert out.num_frames == 12
    # copy-scaled shrinks the stride with the body.
    travel = np.linalg.norm(out.root_pos[-1] - out.root_pos[0])
    assert travel == pytest.approx(0.3 * np.linalg.norm(root[-1] - root[0]), rel=1e-6)


def test_wrong_shapes_are_rejected() -> None:
    q, root = synthetic_motion(5)
    offs = default_canonical_skeleton().offsets
    with pytest.raises(ValueError, match="root_pos must have shape"):
        retarget_clip(load_model("copy"), q, root[:, :2], offs, offs)
    with pytest.raises(ValueError, match="target_offsets"):
        OnlineRetargeter(load_model("copy"), offs, offs[:5])


@pytest.mark.parametrize("name", ["copy", "copy-scaled", "nkn", "pmnet"])
def test_online_path_matches_clip_path(name: str) -> None:
    torch.manual_seed(1)
    model = build_model(name, **TINY.get(name, {})).eval()
    q, root = synthetic_motion(15)
    src = default_canonical_skeleton().offsets
    tgt = src * np.linspace(0.4, 0.6, 22)[:, None]
    clip_q, clip_root = retarget_clip(model, q, root, src, tgt)
    online = OnlineRetargeter(model, src, tgt)
    for _ in range(2):  # reset() really starts over
        online.reset()
        for t in range(15):
            step_q, step_root = online.step(q[t], root[t])
            np.testing.assert_allclose(np.abs(np.sum(step_q * clip_q[t], axis=-1)), 1.0, atol=1e-4)
            np.testing.assert_allclose(step_root, clip_root[t], atol=1e-4)
