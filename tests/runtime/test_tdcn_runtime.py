"""The numpy TDCN equals the torch model: whole clips (causal and centred) and the causal
online step frame by frame; the export round-trips; any finite stream gives unit rotations."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.nn.inference import LoadedModel, retarget_clip
from robot_retarget.nn.models.registry import build_model
from robot_retarget.nn.models.tdcn import TDCN
from robot_retarget.runtime.model import RuntimeModel
from robot_retarget.runtime.tdcn import FastTDCNRetargeter, run_clip
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from tests.pipeline.stream_equality import assert_same_stream
from tests.runtime.runtime_checks import (
    assert_export_round_trip,
    assert_finite_unit_outputs,
    assert_same_steps,
    smooth_clip,
)

TOL = 1e-5


def _tdcn(causal: bool = True, seed: int = 0, *, residual: bool = True) -> TDCN:
    """A small TDCN (the published depth: 3 blocks, receptive field 81) with every weight and
    statistic perturbed, batch norm included, so each exported number is exercised."""
    torch.manual_seed(seed)
    model = build_model("tdcn", channels=16, causal=causal, residual_rotations=residual)
    assert isinstance(model, TDCN)
    with torch.no_grad():
        for norm in (model.pose_norm, model.quat_norm, model.vel_norm, model.offset_norm):
            norm.mean.normal_(0.0, 0.1)
            norm.std.uniform_(0.5, 2.0)
        for param in model.parameters():
            param.add_(0.05 * torch.randn_like(param))
        for module in model.modules():
            if isinstance(module, torch.nn.BatchNorm1d):
                assert module.running_mean is not None
                assert module.running_var is not None
                module.running_mean.normal_(0.0, 0.1)
                module.running_var.uniform_(0.5, 2.0)
    return model.eval()


def _same_rotations(a: np.ndarray, b: np.ndarray) -> None:
    sign = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    np.testing.assert_allclose(a * sign, b, rtol=0, atol=TOL)


def test_whole_clip_equals_torch_causal_and_centred() -> None:
    src = default_canonical_skeleton().offsets
    tgt = 0.4 * src
    quats, root = smooth_clip(130)  # longer than the 81-frame receptive field
    for causal in (True, False):
        model = _tdcn(causal)
        want_q, want_r = retarget_clip(model, quats, root, src, tgt)
        got_q, got_r = run_clip(model.export_weights(), quats, root, src, tgt)
        _same_rotations(got_q, want_q)
        np.testing.assert_allclose(got_r, want_r, rtol=0, atol=TOL)


@pytest.mark.parametrize("residual", [True, False])
def test_online_step_equals_torch_step_and_clip(residual: bool) -> None:
    """Both output forms (rotations composed after the input's, or the head's own)."""
    src = default_canonical_skeleton().offsets
    tgt = 0.4 * src
    quats, root = smooth_clip(100, seed=1)
    model = _tdcn(residual=residual)
    assert_same_stream(
        LoadedModel(name="tdcn", model=model), src, tgt, quats, root, FastTDCNRetargeter, TOL
    )
    # Step by step equals the whole clip: the ring buffers hold exactly the padded window.
    step = FastTDCNRetargeter(model.export_weights(), src, tgt)
    frames = [step.step(quats[t], root[t]) for t in range(len(quats))]
    want_q, want_r = retarget_clip(model, quats, root, src, tgt)
    _same_rotations(np.stack([q for q, _ in frames]), want_q)
    np.testing.assert_allclose(np.stack([r for _, r in frames]), want_r, rtol=0, atol=TOL)


def test_export_round_trip(tmp_path: Path) -> None:
    runtime = _tdcn().runtime()
    assert runtime is not None
    assert runtime.architecture == "tdcn"
    assert_export_round_trip(runtime, tmp_path / "tdcn.npz")


def test_a_centred_tdcn_has_no_online_step() -> None:
    """It needs future frames: no runtime, and its weights refuse to step."""
    model = _tdcn(causal=False)
    assert model.runtime() is None
    src = default_canonical_skeleton().offsets
    with pytest.raises(ValueError, match="non-causal"):
        FastTDCNRetargeter(model.export_weights(), src, src)


_RUNTIME = RuntimeModel(name="tdcn", architecture="tdcn", weights=_tdcn(seed=3).export_weights())


@settings(max_examples=25, deadline=None)
@given(
    arrays(np.float64, (5, 22, 4), elements=st.floats(-1e6, 1e6)),
    arrays(np.float64, (5, 3), elements=st.floats(-1e6, 1e6)),
)
def test_any_finite_stream_gives_finite_unit_quaternions(raw: np.ndarray, root: np.ndarray) -> None:
    assert_finite_unit_outputs(_RUNTIME, raw, root)


def test_the_shipped_tdcn_runtime_is_its_checkpoint() -> None:
    """``tdcn`` streams without torch from its .npz, and that file is the shipped .pt's."""
    from robot_retarget.nn.inference import load_model
    from robot_retarget.runtime.loader import load_runtime_model, runtime_of

    shipped = load_runtime_model("tdcn")
    assert isinstance(shipped, RuntimeModel)
    assert shipped.architecture == "tdcn"
    exported = runtime_of(load_model("tdcn"))
    assert exported is not None
    assert_same_steps(shipped, exported, frames=30, seed=5, scale=0.4, atol=0.0)
