"""SAN: one encoder per skeleton topology, the file's own joints in, the canonical skeleton
out; frame-by-frame equals the clip; native batches train."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from robot_retarget.nn.dataset import WindowSampler, fit_features, load_dataset
from robot_retarget.nn.inference import retarget_clip
from robot_retarget.nn.models.optimizers import make_optimizers
from robot_retarget.nn.models.registry import build_discriminator, build_model
from robot_retarget.nn.models.san import SAN
from robot_retarget.nn.models.training import training_step
from robot_retarget.nn.train import native_domains
from robot_retarget.skeleton.armatures import TopologyError
from tests.nn.conftest import make_mocap_dir

TINY = {"channels": (4, 8), "static_channels": 2, "kernel_size": 3}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    root = make_mocap_dir(tmp_path_factory.mktemp("mocap"))
    return load_dataset(root, use_cache=False)


def _san(dataset, **config: object) -> SAN:  # type: ignore[no-untyped-def]
    torch.manual_seed(0)
    model = build_model("san", domains=native_domains(dataset), **{**TINY, **config})
    assert isinstance(model, SAN)
    return model


def test_every_fixture_skeleton_gets_its_own_encoder(dataset) -> None:  # type: ignore[no-untyped-def]
    model = _san(dataset)
    names = {c.native.topology.name for c in dataset.clips if c.native is not None}
    assert set(model.domain_names) == {"canonical"} | names
    for clip in dataset.clips:
        assert clip.native is not None
        assert model.domain_of(clip.native.topology) is not None


def test_the_native_path_reads_the_files_joints(dataset) -> None:  # type: ignore[no-untyped-def]
    model = _san(dataset).eval()
    clip = next(c for c in dataset.clips if c.native is not None and c.num_frames >= 12)
    assert clip.native is not None
    args = (clip.local_quats, clip.root_pos, clip.offsets, 0.5 * clip.offsets)
    q_nat, _r_nat = retarget_clip(model, *args, native=clip.native)
    q_can, _ = retarget_clip(model, *args)
    assert q_nat.shape == q_can.shape == (clip.num_frames, 22, 4)
    assert np.allclose(np.linalg.norm(q_nat, axis=-1), 1.0)
    assert not np.allclose(q_nat, q_can)  # another encoder read other joints
    # The joints come from the native pose: changing one of them changes the output.
    nudged = clip.native.local_quats.copy()
    nudged[:, 5] = nudged[:, 5][:, [1, 0, 2, 3]]
    q_nudged, _ = retarget_clip(model, *args, native=replace(clip.native, local_quats=nudged))
    assert not np.allclose(q_nudged, q_nat)


def test_models_without_native_encoders_refuse_a_native_pose(dataset) -> None:  # type: ignore[no-untyped-def]
    clip = dataset.clips[0]
    args = (clip.local_quats, clip.root_pos, clip.offsets, clip.offsets)
    with pytest.raises(ValueError, match="reads canonical joints only"):
        retarget_clip(build_model("copy"), *args, native=clip.native)
    canonical_only = build_model("san", **TINY)
    with pytest.raises(ValueError, match="no encoder for skeleton"):
        retarget_clip(canonical_only, *args, native=clip.native)


def test_a_non_homeomorphic_domain_is_refused() -> None:
    spec = {
        "joint_names": ["h", "s", "c", "n", "la", "ra", "ll", "rl"],
        "parents": [-1, 0, 1, 2, 1, 2, 0, 0],
        "end_effectors": [6, 7, 3, 4, 5],
    }
    with pytest.raises(TopologyError, match="not homeomorphic"):
        build_model("san", domains={"odd": spec}, **TINY)


def test_non_causal_san_has_no_online_step(dataset) -> None:  # type: ignore[no-untyped-def]
    model = _san(dataset, causal=False).eval()
    q = torch.tensor(dataset.clips[0].local_quats[None, 0], dtype=torch.float32)
    off = torch.tensor(dataset.clips[0].offsets[None], dtype=torch.float32)
    model.reset()
    with pytest.raises(ValueError, match="non-causal"):
        model.step(q, torch.zeros(1, 3), off, off)


def test_native_batches_hold_one_skeleton_and_match_the_canonical_window(dataset) -> None:  # type: ignore[no-untyped-def]
    sampler = WindowSampler(dataset, window_frames=12, batch_size=3, native=True, seed=2)
    seen: set[str | None] = set()
    for step in range(16):
        b = sampler.sample(step)
        seen.add(b.native_domain)
        if b.native_domain is None:  # a canonical batch: the live path's input
            assert b.native_quats is None
            assert b.native_offsets is None
            continue
        assert b.native_quats is not None
        assert b.native_offsets is not None
        a = b.native_quats.shape[2]
        assert b.native_offsets.shape == (3, a, 3)
        # The native window is the canonical window's: find it in its clip.
        window = b.src_local_quats[0].numpy()
        found = [
            (c, s)
            for c in sampler.clips
            if c.native is not None and c.native.topology.name == b.native_domain
            for s in range(c.num_frames - 11)
            if np.allclose(c.local_quats[s : s + 12], window, atol=1e-6)
        ]
        assert found
        clip, start = found[0]
        assert clip.native is not None
        native = clip.native.local_quats[start : start + 12]
        assert np.allclose(native, b.native_quats[0].numpy(), atol=1e-6)
    assert None in seen
    assert len(seen) > 2


def test_native_batches_train(dataset) -> None:  # type: ignore[no-untyped-def]
    model = _san(dataset)
    torch.manual_seed(1)
    disc = build_discriminator("san", channels=8, dilations=(1, 2))
    opt = make_optimizers(model, disc, lr=3e-3)
    sampler = WindowSampler(
        dataset, window_frames=12, batch_size=4, native=True, canonical_share=0.0, seed=0
    )
    batch = sampler.sample(0)
    model.fit_normalization(*fit_features(WindowSampler(dataset, window_frames=12), batches=2))
    assert batch.native_domain is not None
    encoder = model.encoders[model.domain_names.index(batch.native_domain)]
    before = [p.detach().clone() for p in encoder.parameters()]
    history = [training_step(model, disc, batch, opt) for _ in range(15)]
    assert history[-1]["reconstruction"] < 0.7 * history[0]["reconstruction"]
    # The batch's own skeleton's encoder is the one that learned to read it.
    assert any(not torch.equal(a, b) for a, b in zip(before, encoder.parameters(), strict=True))


def test_checkpoint_round_trip_keeps_the_domains(dataset, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from robot_retarget.nn.checkpoint import load_checkpoint, save_checkpoint

    model = _san(dataset)
    path = tmp_path / "san.pt"
    save_checkpoint(path, model)
    loaded = load_checkpoint(path).model
    assert isinstance(loaded, SAN)
    assert loaded.domain_names == model.domain_names
    for a, b in zip(model.state_dict().values(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b)
