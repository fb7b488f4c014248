"""The keypoint model's numpy runtime equals the torch model (whole clips, both poolings, and
the causal one-frame step), and its file round-trips with clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import ModelLoadError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.nn.models.agnostic2d import Agnostic2D, rotation_6d_to_matrix
from robot_retarget.runtime.agnostic2d import (
    Agnostic2DRuntime,
    Agnostic2DStep,
    MirrorAveragedStep,
    load_agnostic2d,
    load_keypoint_model,
    save_agnostic2d,
)


@pytest.fixture(scope="module")
def model() -> Agnostic2D:
    torch.manual_seed(0)
    return Agnostic2D(channels=24, static_hidden=16, head_hidden=32).eval()


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(2 * np.arccos(np.clip(np.abs((a * b).sum(-1)), 0, 1))))


@pytest.mark.parametrize("causal", [True, False])
def test_runtime_equals_torch(model: Agnostic2D, causal: bool) -> None:
    x = torch.randn(1, 50, 51)
    with torch.no_grad():
        ref = quat.from_matrix(rotation_6d_to_matrix(model(x, causal)[0])[0].double().numpy())
    rt = Agnostic2DRuntime(model.export_weights())
    assert _angle(rt.run_features(x[0].double().numpy(), causal=causal), ref) < 1e-4
    if causal:
        step = Agnostic2DStep(rt.weights)
        online = np.stack([step.step_features(f) for f in x[0].double().numpy()])
        assert _angle(online, ref) < 1e-4


def test_a_centred_model_looks_ahead_equals_torch_and_round_trips(tmp_path: Path) -> None:
    """``centered=True`` (convert's model): the runtime equals torch on whole clips, a frame's
    answer depends on the frames after it (a causal model's does not), the flag survives the
    file, and every causal use is refused with the reason."""
    torch.manual_seed(1)
    centred = Agnostic2D(channels=24, static_hidden=16, head_hidden=32, centered=True).eval()
    causal = Agnostic2D(channels=24, static_hidden=16, head_hidden=32).eval()
    x = torch.randn(1, 50, 51)
    with torch.no_grad():
        ref = quat.from_matrix(rotation_6d_to_matrix(centred(x, False)[0])[0].double().numpy())
    rt = load_agnostic2d(
        save_agnostic2d(Agnostic2DRuntime(centred.export_weights()), tmp_path / "c.npz")
    )
    assert rt.centered
    assert not Agnostic2DRuntime(causal.export_weights()).centered
    feats = x[0].double().numpy()
    assert _angle(rt.run_features(feats, causal=False), ref) < 1e-4
    later = feats.copy()
    later[30:] += 1.0  # only frames from 30 on change
    # The causal model pooled causally (its static codes pooled over the clip would see ahead).
    for m, pooled_causally in ((rt, False), (Agnostic2DRuntime(causal.export_weights()), True)):
        now = m.run_features(feats, causal=pooled_causally)[20:30]
        moved = _angle(m.run_features(later, causal=pooled_causally)[20:30], now)
        assert (moved > 1e-3) == (m is rt)
    with pytest.raises(ValueError, match="looks ahead"):
        centred(x, True)
    with pytest.raises(ModelLoadError, match="looks ahead"):
        rt.run_features(feats, causal=True)
    with pytest.raises(ModelLoadError, match=r"looks ahead.*stream with a causal one"):
        rt.online()
    with pytest.raises(ValueError, match="looks ahead"):
        Agnostic2DStep(rt.weights)
    with pytest.raises(ValueError, match="odd kernel"):
        Agnostic2D(kernel=4, centered=True)


def test_file_round_trip_and_errors(model: Agnostic2D, tmp_path: Path) -> None:
    rt = Agnostic2DRuntime(model.export_weights(), data_hash="abc")
    path = save_agnostic2d(rt, tmp_path / "m.npz")
    back = load_agnostic2d(path)
    assert back.data_hash == "abc"
    assert back.receptive_field == model.receptive_field
    feats = np.random.default_rng(0).normal(size=(20, 51))
    assert _angle(back.run_features(feats, causal=True), rt.run_features(feats, causal=True)) < 1e-5
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["head.1.0"] = arrays["head.1.0"][:5]
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ModelLoadError, match="do not fit agnostic2d"):
        load_agnostic2d(tmp_path / "bad.npz")
    with pytest.raises(ModelLoadError, match="not found"):
        load_agnostic2d(tmp_path / "missing.npz")


def _checkpoint(path: Path, seed: int, *, centered: bool = True) -> Path:
    from robot_retarget.nn.agnostic2d_training import save_keypoint_checkpoint

    torch.manual_seed(seed)
    m = Agnostic2D(channels=24, static_hidden=16, head_hidden=32, centered=centered).eval()
    return save_keypoint_checkpoint(path, m, data_hash="d", metadata={"step": seed})


def test_an_ensemble_averages_its_models_and_round_trips(tmp_path: Path) -> None:
    """``export`` of several checkpoints: one file (format 2) whose answer is the mean of its
    models' answers, provenance per model; every model loads with its own weights."""
    from robot_retarget.nn.agnostic2d_training import export_keypoint_checkpoint
    from robot_retarget.runtime.agnostic2d import mean_rotation
    from robot_retarget.runtime.npz_file import read_runtime_npz

    pts = [_checkpoint(tmp_path / f"m{i}.pt", i) for i in range(3)]
    path = export_keypoint_checkpoint(pts, tmp_path / "ens.npz", force=False)
    ens = load_agnostic2d(path)
    assert len(ens.members) == 3
    assert ens.centered
    assert ens.name == "ens"
    assert [m["checkpoint"] for m in ens.metadata["ensemble"]] == ["m0.pt", "m1.pt", "m2.pt"]
    assert read_runtime_npz(path, "x")[1]["format"] == 2
    singles = [load_agnostic2d(p.with_suffix(".npz")) for p in pts]  # each model's own runtime
    assert read_runtime_npz(pts[0].with_suffix(".npz"), "x")[1]["format"] == 1
    xy = np.random.default_rng(5).uniform(200, 700, (30, 17, 2))
    valid = np.ones((30, 17), dtype=bool)
    answers = [m.run_clip(xy, valid, causal=False) for m in singles]
    assert _angle(ens.run_clip(xy, valid, causal=False), mean_rotation(answers)) < 1e-6
    # The models differ, so the mean is none of them.
    assert min(_angle(ens.run_clip(xy, valid, causal=False), a) for a in answers) > 1e-3
    with pytest.raises(ModelLoadError, match="looks ahead"):
        ens.online()


def test_an_ensemble_is_refused_where_it_cannot_run(tmp_path: Path) -> None:
    """Causal and centred models do not mix; a file whose member is damaged or whose member
    count is wrong names what is wrong. (A causal ensemble streams: see the next test.)"""
    from robot_retarget.nn.agnostic2d_training import export_keypoint_checkpoint

    a, b = _checkpoint(tmp_path / "a.pt", 0), _checkpoint(tmp_path / "b.pt", 1, centered=False)
    with pytest.raises(ModelLoadError, match="all be centred"):
        export_keypoint_checkpoint([a, b], tmp_path / "mixed.npz", force=False)
    c = _checkpoint(tmp_path / "c.pt", 2, centered=False)
    causal = load_agnostic2d(export_keypoint_checkpoint([b, c], tmp_path / "cc.npz", force=False))
    q = causal.run_clip(np.full((5, 17, 2), 300.0), np.ones((5, 17), bool), causal=True)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)
    with np.load(tmp_path / "cc.npz") as z:
        arrays = {k: z[k] for k in z.files}
    damaged = {k: v for k, v in arrays.items() if k != "ensemble.1.head.1.0"}
    np.savez(tmp_path / "damaged.npz", **damaged)
    with pytest.raises(ModelLoadError, match="do not fit agnostic2d"):
        load_agnostic2d(tmp_path / "damaged.npz")
    import json

    meta = json.loads(str(arrays["__meta__"]))
    for members in (0, "2", 3):
        np.savez(
            tmp_path / "count.npz",
            **{**arrays, "__meta__": np.array(json.dumps({**meta, "members": members}))},
        )
        with pytest.raises(ModelLoadError, match=r"members|do not fit"):
            load_agnostic2d(tmp_path / "count.npz")


def test_shipped_keypoint_models_load() -> None:
    """The causal model streams; the centred one (convert's) lifts whole clips only."""
    rt = load_keypoint_model()
    assert rt.metadata.get("validation_subjects")
    assert rt.checkpoint_sha256
    assert not rt.centered
    step = rt.online()
    q = step.step(np.full((17, 2), np.nan), np.zeros(17, dtype=bool))
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)
    clip = load_keypoint_model(whole_clip=True)
    assert clip.centered
    assert clip.name == "agnostic2d_clip"
    assert clip.metadata["validation_subjects"] == rt.metadata["validation_subjects"]
    assert "centered=true" in clip.metadata["command"]
    assert load_keypoint_model("agnostic2d_clip").checkpoint_sha256 == clip.checkpoint_sha256
    assert (
        load_keypoint_model("agnostic2d", whole_clip=True).checkpoint_sha256 == rt.checkpoint_sha256
    )
    with pytest.raises(ModelLoadError, match="looks ahead"):
        clip.online()
    xy = np.random.default_rng(3).uniform(200, 700, (12, 17, 2))
    q = clip.run_clip(xy, np.ones((12, 17), dtype=bool), causal=False, mirror_average=True)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)


@pytest.mark.parametrize("name", ["agnostic2d", "agnostic2d_clip"])
def test_shipped_runtime_is_the_shipped_checkpoint(name: str, tmp_path: Path) -> None:
    """Each shipped .npz is ``export`` of its .pt files (an ensemble's: every model's, listed
    in its metadata): the same weights and the checkpoints' hashes."""
    import hashlib

    from robot_retarget.nn.agnostic2d_training import export_keypoint_checkpoint

    shipped = load_keypoint_model(name)
    assert shipped.path is not None
    listed = shipped.metadata.get("ensemble")
    pts = (
        [shipped.path.parent / m["checkpoint"] for m in listed]
        if listed
        else [shipped.path.with_suffix(".pt")]
    )
    out = tmp_path / f"{name}.npz"  # an ensemble is named after its file
    fresh = load_agnostic2d(export_keypoint_checkpoint(pts, out, force=False))
    assert shipped.checkpoint_sha256 == hashlib.sha256(pts[0].read_bytes()).hexdigest()
    if listed:
        for m, pt in zip(listed, pts, strict=True):
            assert m["checkpoint_sha256"] == hashlib.sha256(pt.read_bytes()).hexdigest()
    assert fresh.centered == shipped.centered
    assert len(fresh.members) == len(shipped.members)
    for a_model, b_model in zip(fresh.members, shipped.members, strict=True):
        b_arrays = b_model.arrays()
        for key, a in a_model.arrays().items():
            np.testing.assert_array_equal(a, b_arrays[key], err_msg=key)


@settings(max_examples=60)
@given(
    st.lists(st.floats(-1e12, 1e12, allow_nan=False), min_size=34, max_size=34),
    st.lists(st.booleans(), min_size=17, max_size=17),
)
def test_any_keypoints_give_unit_rotations(coords: list[float], seen: list[bool]) -> None:
    """Whatever a sender's points are (huge, coincident, mostly missing), the model's output is
    22 finite unit quaternions: nothing a camera sends can make the optimizer's input invalid."""
    step = load_keypoint_model().online()
    xy = np.array(coords).reshape(17, 2)
    for _ in range(3):
        q = step.step(xy, np.array(seen))
        assert np.isfinite(q).all()
        np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)


_CLIP_MODEL = load_keypoint_model(whole_clip=True)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.floats(-1e12, 1e12, allow_nan=False), min_size=102, max_size=102),
    st.lists(st.booleans(), min_size=51, max_size=51),
)
def test_any_keypoints_give_unit_rotations_in_convert(
    coords: list[float], seen: list[bool]
) -> None:
    """The same for ``convert``'s lifting (the shipped clip model, every model of it, image and
    mirror): three frames of anything give finite unit quaternions."""
    q = _CLIP_MODEL.run_clip(
        np.array(coords).reshape(3, 17, 2),
        np.array(seen).reshape(3, 17),
        causal=False,
        mirror_average=True,
    )
    assert np.isfinite(q).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)


def test_mirror_average_is_exactly_mirror_symmetric() -> None:
    """convert's mirrored-image averaging: mirroring the image mirrors the answer."""
    from robot_retarget.keypoints.coco17 import FLIP_PAIRS
    from robot_retarget.skeleton.mirror import mirror_rotations

    rt = load_keypoint_model()
    rng = np.random.default_rng(4)
    xy = rng.uniform(200, 700, (40, 17, 2))
    valid = rng.random((40, 17)) > 0.1
    flip = np.arange(17)
    for a, b in FLIP_PAIRS:
        flip[a], flip[b] = b, a
    mirrored = xy[:, flip].copy()
    mirrored[..., 0] = 1000.0 - mirrored[..., 0]
    q = rt.run_clip(xy, valid, causal=False, mirror_average=True)
    qm = rt.run_clip(mirrored, valid[:, flip], causal=False, mirror_average=True)
    dots = np.abs((mirror_rotations(q) * qm).sum(-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-9)
    np.testing.assert_allclose(mirror_rotations(mirror_rotations(q)), q)


def test_the_mirror_averaged_step_is_the_causal_clip_run_frame_by_frame() -> None:
    """stream's step (image and mirror, averaged) equals run_clip(causal, mirror_average), to
    float32 precision: the step runs in the weights' float32, the clip in float64."""
    rt = load_keypoint_model()
    rng = np.random.default_rng(7)
    xy = rng.uniform(200, 700, (30, 17, 2))
    valid = rng.random((30, 17)) > 0.15
    xy[~valid] = np.nan  # what the sources hand over for a missing point
    clip = rt.run_clip(xy, valid, causal=True, mirror_average=True)
    step = rt.online()
    online = np.stack([step.step(xy[t], valid[t]) for t in range(30)])
    assert _angle(online, clip) < 2e-5  # float32: ~1e-6 rad here; arccos resolves ~1e-8
    plain = rt.online(mirror_average=False)
    direct = np.stack([plain.step(xy[t], valid[t]) for t in range(30)])
    assert _angle(direct, rt.run_clip(xy, valid, causal=True)) < 2e-5
    assert _angle(direct, online) > 1e-3  # the mirror changes the answer
    step.reset()
    np.testing.assert_allclose(step.step(xy[0], valid[0]), online[0])


def test_keypoint_benchmark_times_both_steps_side_by_side() -> None:
    from robot_retarget.nn.keypoint_benchmark import time_keypoint_model

    rows = time_keypoint_model(frames=20, warmup=2, repeats=1, threads=1)
    modes = {r["mode"]: r for r in rows}
    assert set(modes) == {
        "online",
        "online-numpy",
        "online-numpy-single",
        "clip-numpy",
        "convert-numpy",
        "clip",
    }
    assert modes["online"]["frames"] == modes["online-numpy"]["frames"] == 20
    assert modes["online-numpy-single"]["frames"] == 20
    assert all(r["median_ms"] > 0.0 for r in rows)


def test_a_causal_ensemble_streams_as_it_lifts_clips(tmp_path: Path) -> None:
    """Frame by frame, compiled or numpy, with the mirror or without, a causal ensemble's step
    is its whole-clip causal answer (every model's averaged, as run_clip does), to float32."""
    from robot_retarget.nn.agnostic2d_training import export_keypoint_checkpoint

    pts = [_checkpoint(tmp_path / f"c{i}.pt", i, centered=False) for i in range(2)]
    ens = load_agnostic2d(export_keypoint_checkpoint(pts, tmp_path / "cc.npz", force=False))
    rng = np.random.default_rng(3)
    xy = rng.uniform(200, 700, (25, 17, 2))
    valid = rng.random((25, 17)) > 0.15
    xy[~valid] = np.nan
    first = load_agnostic2d(pts[0].with_suffix(".npz"))
    for mirror in (True, False):
        want = ens.run_clip(xy, valid, causal=True, mirror_average=mirror)
        alone = first.run_clip(xy, valid, causal=True, mirror_average=mirror)
        assert _angle(want, alone) > 1e-3  # the second model counts
        steps = [ens.online(mirror_average=mirror)]
        if mirror:
            steps.append(MirrorAveragedStep(ens.weights, ensemble=ens.ensemble, compiled=False))
        for step in steps:
            got = np.stack([step.step(xy[t], valid[t]) for t in range(len(xy))])
            assert _angle(got, want) < 1e-4
