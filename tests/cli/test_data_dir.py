"""The default ``--data`` of train / eval / eval-robot / crossval: $ROBOT_RETARGET_DATA/mocap
when set, else ../shared/data/mocap next to the checkout."""

from __future__ import annotations

import argparse
from pathlib import Path
from types import ModuleType

import pytest

from robot_retarget.cli import crossval_cmd, data_dir, eval_cmd, eval_robot_cmd, train_cmd

CHECKOUT_MOCAP = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "mocap"

COMMANDS: list[tuple[ModuleType, list[str]]] = [
    (train_cmd, ["--model", "pmnet", "--out", "runs/x"]),
    (eval_cmd, []),
    (eval_robot_cmd, []),
    (crossval_cmd, ["--model", "residual", "--out", "runs/x", "--steps", "1"]),
]


def _data_default(module: ModuleType, argv: list[str]) -> str:
    parser = argparse.ArgumentParser()
    module.configure(parser)
    return str(parser.parse_args(argv).data)


def test_environment_variable_is_honoured(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROBOT_RETARGET_DATA", str(tmp_path))
    assert data_dir.shared_data_dir() == tmp_path
    assert data_dir.default_mocap_dir() == tmp_path / "mocap"
    for module, argv in COMMANDS:
        assert _data_default(module, argv) == str(tmp_path / "mocap"), module.NAME
        assert _data_default(module, [*argv, "--data", "elsewhere"]) == "elsewhere"


@pytest.mark.parametrize("value", [None, ""])
def test_checkout_default_without_the_variable(
    value: str | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    if value is None:
        monkeypatch.delenv("ROBOT_RETARGET_DATA", raising=False)
    else:
        monkeypatch.setenv("ROBOT_RETARGET_DATA", value)
    assert data_dir.default_mocap_dir() == CHECKOUT_MOCAP
    for module, argv in COMMANDS:
        assert _data_default(module, argv) == str(CHECKOUT_MOCAP), module.NAME
