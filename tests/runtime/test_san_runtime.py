"""The numpy SAN step equals the torch model (step by step and the whole clip), with the
static features and the unpooling folded in; the export round-trips; any finite stream gives
unit rotations."""

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
from robot_retarget.nn.models.san import SAN
from robot_retarget.runtime.model import RuntimeModel
from robot_retarget.runtime.san import FastSANRetargeter
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from tests.pipeline.stream_equality import assert_same_stream
from tests.runtime.runtime_checks import (
    assert_export_round_trip,
    assert_finite_unit_outputs,
    smooth_clip,
)
from tests.runtime.test_tdcn_runtime import _same_rotations

TOL = 1e-5


def _san(causal: bool = True, seed: int = 0) -> SAN:
    """A small SAN (the published depth: two levels, pooled to the primal skeleton) with its
    root statistics perturbed, so each exported number is exercised."""
    torch.manual_seed(seed)
    model = build_model("san", channels=(6, 8), static_channels=3, kernel_size=4, causal=causal)
    assert isinstance(model, SAN)
    with torch.no_grad():
        model.root_norm.mean.normal_(0.0, 0.01)
        model.root_norm.std.uniform_(0.005, 0.05)
    return model.eval()


def test_online_step_equals_torch_step_and_clip() -> None:
    src = default_canonical_skeleton().offsets
    tgt = 0.4 * src
    quats, root = smooth_clip(60, seed=1)  # longer than the 13-frame receptive field
    model = _san()
    assert_same_stream(
        LoadedModel(name="san", model=model), src, tgt, quats, root, FastSANRetargeter, TOL
    )
    step = FastSANRetargeter(model.export_weights(), src, tgt)
    frames = [step.step(quats[t], root[t]) for t in range(len(quats))]
    want_q, want_r = retarget_clip(model, quats, root, src, tgt)
    _same_rotations(np.stack([q for q, _ in frames]), want_q)
    np.testing.assert_allclose(np.stack([r for _, r in frames]), want_r, rtol=0, atol=TOL)


def test_export_round_trip(tmp_path: Path) -> None:
    runtime = _san().runtime()
    assert runtime is not None
    assert runtime.architecture == "san"
    assert_export_round_trip(runtime, tmp_path / "san.npz")


def test_a_centred_san_has_no_online_step() -> None:
    model = _san(causal=False)
    assert model.runtime() is None
    src = default_canonical_skeleton().offsets
    with pytest.raises(ValueError, match="non-causal"):
        FastSANRetargeter(model.export_weights(), src, src)


_RUNTIME = RuntimeModel(name="san", architecture="san", weights=_san(seed=3).export_weights())


@settings(max_examples=25, deadline=None)
@given(
    arrays(np.float64, (5, 22, 4), elements=st.floats(-1e6, 1e6)),
    arrays(np.float64, (5, 3), elements=st.floats(-1e6, 1e6)),
)
def test_any_finite_stream_gives_finite_unit_quaternions(raw: np.ndarray, root: np.ndarray) -> None:
    assert_finite_unit_outputs(_RUNTIME, raw, root)
