"""``export``: a checkpoint → the numpy runtime the live path loads without torch."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from robot_retarget.cli import export_cmd
from robot_retarget.errors import ModelLoadError, MotionFormatError
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
    with pytest.raises(MotionFormatError, match="--force"):
        export_cmd.run(_args(str(CHECKPOINT_DIR / "default.pt"), "--out", str(out)))
    with pytest.raises(MotionFormatError, match=r"\.npz"):
        export_cmd.run(_args(str(CHECKPOINT_DIR / "default.pt"), "--out", str(tmp_path / "x.pt")))


def test_built_in_models_need_no_export() -> None:
    with pytest.raises(ModelLoadError, match="built-in"):
        export_cmd.run(_args("copy"))
