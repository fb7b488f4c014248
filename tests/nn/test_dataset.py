"""Dataset: loading and caching clips, subject split, augmentation, window batches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.nn import dataset as ds
from robot_retarget.nn.dataset import (
    Augmentation,
    DatasetError,
    WindowSampler,
    augment_offsets,
    fit_features,
    leg_length,
    load_dataset,
    subject_of,
)
from robot_retarget.skeleton.canonical import MIRROR_PAIRS, Joint, default_canonical_skeleton


def test_subject_is_first_folder_else_file_prefix(tmp_path: Path) -> None:
    assert subject_of(tmp_path / "07" / "07_01.bvh", tmp_path) == "07"
    assert subject_of(tmp_path / "a" / "b" / "x.bvh", tmp_path) == "a"
    assert subject_of(tmp_path / "13_10.bvh", tmp_path) == "13"


def test_load_resamples_and_names_subjects(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, fps=30.0, cache_dir=cache_dir)
    assert data.subjects == ("s1", "s2", "s3")
    assert len(data.clips) == 5
    daz = next(c for c in data.clips if c.name == "s3/crlf_tabs.bvh")
    assert daz.fps == pytest.approx(30.0)  # the 24 fps clip was resampled
    for c in data.clips:
        assert c.local_quats.shape == (c.num_frames, 22, 4)
        np.testing.assert_allclose(np.linalg.norm(c.local_quats, axis=-1), 1.0, atol=1e-9)
        assert c.root_pos.shape == (c.num_frames, 3)
        assert 1.0 < c.height_m < 2.2
        assert c.motion().num_frames == c.num_frames


def test_cache_is_reused_and_keyed_by_content(
    mocap_dir: Path, cache_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = load_dataset(mocap_dir, cache_dir=cache_dir)
    assert len(list(cache_dir.glob("dataset-*.npz"))) == 1

    def no_parse(*args: object) -> None:
        raise AssertionError("parsed BVH although the cache was valid")

    monkeypatch.setattr(ds, "_load_clip", no_parse)
    again = load_dataset(mocap_dir, cache_dir=cache_dir)
    assert again.data_hash == first.data_hash
    for a, b in zip(first.clips, again.clips, strict=True):
        assert (a.name, a.subject) == (b.name, b.subject)
        np.testing.assert_array_equal(a.local_quats, b.local_quats)
        np.testing.assert_array_equal(a.offsets, b.offsets)
    monkeypatch.undo()
    # Changing a file's bytes changes the hash, so the stale cache is not served.
    clip = mocap_dir / "s3" / "crlf_tabs.bvh"
    clip.write_bytes(clip.read_bytes() + b"\n")
    changed = load_dataset(mocap_dir, cache_dir=cache_dir)
    assert changed.data_hash != first.data_hash
    assert len(list(cache_dir.glob("dataset-*.npz"))) == 2


def test_split_by_subject(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    train, val = data.split(("s2",))
    assert train.subjects == ("s1", "s3")
    assert val.subjects == ("s2",)
    assert {c.name for c in train.clips}.isdisjoint({c.name for c in val.clips})
    assert train.data_hash != val.data_hash != data.data_hash
    with pytest.raises(DatasetError, match="not in the data"):
        data.split(("s9",))
    with pytest.raises(DatasetError, match="leave at least one"):
        data.split(("s1", "s2", "s3"))


def test_missing_or_empty_folder_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="no such data folder"):
        load_dataset(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match=r"no \.bvh files"):
        load_dataset(tmp_path / "empty")
    (tmp_path / "clip.bvh").write_text("HIERARCHY\n")
    with pytest.raises(DatasetError, match="a file, not a folder: --data names the folder"):
        load_dataset(tmp_path / "clip.bvh")  # it said "no such data folder"


@settings(max_examples=25)
@given(seed=st.integers(0, 2**32 - 1))
def test_augmentation_is_symmetric_and_bounded(seed: int) -> None:
    base = default_canonical_skeleton().offsets
    aug = Augmentation(global_scale=(0.5, 1.5), bone_scale=(0.8, 1.2))
    out = augment_offsets(base, np.random.default_rng(seed), aug)
    lengths, base_len = np.linalg.norm(out, axis=-1), np.linalg.norm(base, axis=-1)
    ratio = lengths[base_len > 0] / base_len[base_len > 0]
    assert np.all(ratio >= 0.5 * 0.8 - 1e-12)
    assert np.all(ratio <= 1.5 * 1.2 + 1e-12)
    for left, right in MIRROR_PAIRS:
        l_len, r_len = lengths[Joint[left]], lengths[Joint[right]]
        assert l_len == pytest.approx(r_len)
    # Directions are kept: only lengths change.
    nz = base_len > 0
    cos = np.sum(out[nz] * base[nz], axis=-1) / (lengths[nz] * base_len[nz])
    np.testing.assert_allclose(cos, 1.0, atol=1e-12)


def test_sampler_batches_are_reproducible_and_well_formed(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    robot = {"bot": default_canonical_skeleton().offsets * 0.3}
    sampler = WindowSampler(
        data, window_frames=8, batch_size=16, robot_offsets=robot, real_motion=True, seed=3
    )
    a, b = sampler.sample(5), sampler.sample(5)
    c = sampler.sample(6)
    torch.testing.assert_close(a.src_local_quats, b.src_local_quats)
    torch.testing.assert_close(a.tgt_offsets, b.tgt_offsets)
    assert not torch.equal(a.src_local_quats, c.src_local_quats)
    assert a.src_local_quats.shape == (16, 8, 22, 4)
    assert a.src_local_quats.dtype == torch.float32
    assert a.real_local_quats is not None
    assert a.real_root_pos is not None
    # B = A samples retarget onto their own skeleton; the others onto a different one.
    same = a.same_skeleton
    torch.testing.assert_close(a.tgt_offsets[same], a.src_offsets[same])
    diff = (a.tgt_offsets[~same] - a.src_offsets[~same]).abs().amax(dim=(1, 2))
    assert bool(torch.all(diff > 0))


def test_sampler_draws_robots_and_scales_source_roots(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    robot = default_canonical_skeleton().offsets * 0.3
    aug = Augmentation(
        global_scale=(2.0, 2.0), bone_scale=(1.0, 1.0), p_same=0.0, p_robot=1.0,
        p_augment_source=1.0,
    )  # fmt: skip
    sampler = WindowSampler(
        data, window_frames=8, batch_size=8, robot_offsets={"bot": robot}, augmentation=aug
    )
    batch = sampler.sample(0)
    for offs in batch.tgt_offsets:
        np.testing.assert_allclose(offs.numpy(), robot, atol=1e-6)
    # A source doubled in size walks a doubled root path: some clip window, × 2.
    for i in range(8):
        src = batch.src_offsets[i].double().numpy()
        root = batch.src_root_pos[i].double().numpy()
        quats = batch.src_local_quats[i].double().numpy()
        found = False
        for clip in data.clips:
            if not np.allclose(src, 2.0 * clip.offsets, atol=1e-5):
                continue
            for start in range(clip.num_frames - 8 + 1):
                window = clip.local_quats[start : start + 8]
                if np.allclose(window, quats, atol=1e-6):
                    np.testing.assert_allclose(
                        root, 2.0 * clip.root_pos[start : start + 8], atol=1e-5
                    )
                    found = True
        assert found


def test_sampler_rejects_windows_longer_than_every_clip(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    with pytest.raises(DatasetError, match="no clip has 500 frames"):
        WindowSampler(data, window_frames=500)


def test_fit_features_cover_source_and_target(mocap_dir: Path, cache_dir: Path) -> None:
    data = load_dataset(mocap_dir, cache_dir=cache_dir)
    sampler = WindowSampler(data, window_frames=8, batch_size=4)
    feats, offsets = fit_features(sampler, batches=2)
    assert feats.local_pos.shape == (16, 8, 22, 3)
    assert feats.root_vel.shape == (16, 8, 4)
    assert offsets.shape == (16, 22, 3)


def test_default_split_keeps_validation_subjects_out_of_training(
    shared_data_dir: Path, tmp_path: Path
) -> None:
    mocap = shared_data_dir / "mocap"
    if not mocap.is_dir():
        pytest.skip(f"no mocap folder in {shared_data_dir}")
    data = load_dataset(mocap, max_frames=40, cache_dir=tmp_path)
    train, val = data.split()
    assert val.subjects == ds.DEFAULT_VALIDATION_SUBJECTS
    assert set(train.subjects).isdisjoint(val.subjects)
    assert len(train.subjects) + len(val.subjects) == 10
    # The robots' canonical skeletons are part of the skeleton set.
    robots = ds.robot_skeletons()
    assert set(robots) == set(ds.DEFAULT_ROBOTS)
    for offs in robots.values():
        assert offs.shape == (22, 3)
        assert leg_length(offs) < 0.5 * leg_length(train.clips[0].offsets)
