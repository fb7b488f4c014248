"""``export``: a checkpoint → the numpy runtime the live path loads without torch."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from robot_retarget.cli import export_cmd
from robot_retarget.errors import ModelLoadError, RetargetError
from robot_retarget.runtime.loader import CHECKPOINT_DIR
from robot_retarget.runtime.model import load_runtime


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    export_cmd.configure(parser)
    return parser.parse_args(list(argv))


def test_export_writes_a_runtime_that_loads(tmp_path: Path) -> None:
    out = tmp_path / "default.npz"
    assert export_cmd.run(_args(str(CHECKPOINT_DIR / "default.pt"), "--out", str(out))) == 0
    model = load_runtime(out)
    assert model.architecture == "residual"
    assert len(model.checkpoint_sha256) == 64
    with pytest.raises(RetargetError, match="--force"):
        export_cmd.run(_args(str(CHECKPOINT_DIR / "default.pt"), "--out", str(out)))
    with pytest.raises(RetargetError, match=r"\.npz"):
        export_cmd.run(_args(str(CHECKPOINT_DIR / "default.pt"), "--out", str(tmp_path / "x.pt")))


def test_what_export_cannot_read_or_write_is_named_before_any_work(tmp_path: Path) -> None:
    """A runtime file, a folder without best.pt, a missing file, an --out folder that does not
    exist: one-line errors, nothing written."""
    default = str(CHECKPOINT_DIR / "default.pt")
    cases = [
        ((str(CHECKPOINT_DIR / "default.npz"),), "a numpy runtime file, already exported"),
        ((str(tmp_path),), "a folder without best.pt"),
        ((str(tmp_path / "gone.pt"),), "no such checkpoint file"),
        ((default, "--out", str(tmp_path / "no" / "x.npz")), r"no such folder; create it first"),
    ]
    for args, message in cases:
        with pytest.raises(RetargetError, match=message):
            export_cmd.run(_args(*args))
    assert list(tmp_path.iterdir()) == []


def test_built_in_models_need_no_export() -> None:
    with pytest.raises(ModelLoadError, match="built-in"):
        export_cmd.run(_args("copy"))


def test_several_keypoint_checkpoints_export_as_one_ensemble(tmp_path: Path) -> None:
    """``export A.pt B.pt --out E.npz``: one runtime of both keypoint models; several
    checkpoints need --out and must all be keypoint models."""
    import torch

    from robot_retarget.nn.agnostic2d_training import save_keypoint_checkpoint
    from robot_retarget.nn.models.agnostic2d import Agnostic2D
    from robot_retarget.runtime.agnostic2d import load_agnostic2d

    pts = []
    for seed in (0, 1):
        torch.manual_seed(seed)
        m = Agnostic2D(channels=16, static_hidden=8, head_hidden=16, centered=True)
        pts.append(
            str(save_keypoint_checkpoint(tmp_path / f"k{seed}.pt", m, data_hash="h", metadata={}))
        )
    out = tmp_path / "ens.npz"
    assert export_cmd.run(_args(*pts, "--out", str(out))) == 0
    assert len(load_agnostic2d(out).members) == 2
    run = tmp_path / "run"  # a training run folder stands for its best.pt
    run.mkdir()
    (run / "best.pt").write_bytes(Path(pts[1]).read_bytes())
    assert export_cmd.run(_args(str(run), "--out", str(tmp_path / "one.npz"))) == 0
    assert len(load_agnostic2d(tmp_path / "one.npz").members) == 1
    other = str(tmp_path / "other.npz")
    with pytest.raises(ModelLoadError, match=r"nope\.pt: no such checkpoint file"):
        export_cmd.run(_args(pts[0], str(tmp_path / "nope.pt"), "--out", other))
    with pytest.raises(ModelLoadError, match="needs --out"):
        export_cmd.run(_args(*pts))
    with pytest.raises(ModelLoadError, match=r"only agnostic2d checkpoints.*default\.pt"):
        export_cmd.run(_args(pts[0], str(CHECKPOINT_DIR / "default.pt"), "--out", other))
    with pytest.raises(ModelLoadError, match=r"k0\.pt: the same checkpoint as .*k0\.pt"):
        export_cmd.run(
            _args(pts[0], str(tmp_path / ".." / tmp_path.name / "k0.pt"), "--out", other)
        )
    assert not Path(other).exists()


def test_a_file_is_judged_by_its_content_not_its_name(tmp_path: Path) -> None:
    """A checkpoint named .npz exports (to an --out that is not itself); a runtime file named
    .pt is named for what it is, not torch's archive error."""
    import shutil

    pt_named_npz = tmp_path / "renamed.npz"
    shutil.copy(CHECKPOINT_DIR / "default.pt", pt_named_npz)
    with pytest.raises(ModelLoadError, match=r"exported onto itself.*give --out"):
        export_cmd.run(_args(str(pt_named_npz)))
    out = tmp_path / "runtime.npz"
    assert export_cmd.run(_args(str(pt_named_npz), "--out", str(out))) == 0
    assert load_runtime(out).architecture == "residual"
    npz_named_pt = tmp_path / "renamed.pt"
    shutil.copy(CHECKPOINT_DIR / "default.npz", npz_named_pt)
    with pytest.raises(ModelLoadError, match="a numpy runtime file, already exported"):
        export_cmd.run(_args(str(npz_named_pt), "--out", str(tmp_path / "again.npz")))
    # convert, stream and the API take either as --model, by content
    from robot_retarget.runtime.loader import load_runtime_model

    assert load_runtime_model(str(npz_named_pt)).architecture == "residual"
    torch_named_npz = load_runtime_model(str(pt_named_npz))
    assert torch_named_npz.architecture == "residual"
