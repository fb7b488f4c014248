"""The numpy runtime file: round trip, and clear errors for files that are not one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn.inference import load_model
from robot_retarget.runtime.loader import load_runtime_model, runtime_of
from robot_retarget.runtime.model import RuntimeModel, load_runtime, save_runtime
from robot_retarget.skeleton.canonical import default_canonical_skeleton


def _steps(model: RuntimeModel, n: int = 20) -> np.ndarray:
    offsets = default_canonical_skeleton().offsets
    step = model.online(offsets, 0.4 * offsets)
    rng = np.random.default_rng(0)
    out = []
    for _ in range(n):
        q = rng.normal(size=(22, 4))
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        quats, root = step.step(q, rng.normal(size=3))
        out.append(np.concatenate([quats.ravel(), root]))
    return np.array(out)


def test_the_shipped_runtime_is_the_shipped_checkpoint() -> None:
    shipped = load_runtime_model("default")
    assert isinstance(shipped, RuntimeModel)
    assert shipped.architecture == "residual"
    exported = runtime_of(load_model("default"))
    assert exported is not None
    np.testing.assert_array_equal(_steps(shipped), _steps(exported))
    assert shipped.data_hash == load_model("default").data_hash


def test_round_trip(tmp_path: Path) -> None:
    model = load_runtime_model("default")
    assert isinstance(model, RuntimeModel)
    again = load_runtime(save_runtime(model, tmp_path / "m.npz"))
    np.testing.assert_array_equal(_steps(model), _steps(again))
    assert again.architecture == model.architecture


def test_baselines_need_no_file() -> None:
    for name in ("copy", "copy-scaled"):
        model = load_runtime_model(name)
        assert isinstance(model, RuntimeModel)
        assert model.weights is None


def test_files_that_are_not_runtimes_are_refused(tmp_path: Path) -> None:
    good = load_runtime_model("default")
    assert isinstance(good, RuntimeModel)
    path = save_runtime(good, tmp_path / "good.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    cases = {
        "no __meta__": {k: v for k, v in arrays.items() if k != "__meta__"},
        "format": {**arrays, "__meta__": np.array(json.dumps({"format": 99}))},
        "unknown architecture": {
            **arrays, "__meta__": np.array(json.dumps({"format": 1, "architecture": "sans"}))
        },
        "no weights named": {k: v for k, v in arrays.items() if not k.startswith("to_delta")},
        "do not fit": {**arrays, "to_delta.0": arrays["to_delta.0"][:, :5]},
    }  # fmt: skip
    for needle, content in cases.items():
        bad = tmp_path / f"{needle.replace(' ', '_')}.npz"
        np.savez(bad, **content)
        with pytest.raises(ModelLoadError, match=needle):
            load_runtime(bad)
    with pytest.raises(ModelLoadError, match=r"2D keypoint model.*--keypoint-model"):
        load_runtime_model("agnostic2d")  # the shipped keypoint model, given as --model
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(ModelLoadError, match="not a runtime"):
        load_runtime(tmp_path / "text.npz")
    with pytest.raises(ModelLoadError, match="not found"):
        load_runtime(tmp_path / "missing.npz")
