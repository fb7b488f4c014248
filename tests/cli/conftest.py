"""Fixtures for the command tests: a folder nobody may write into, a guard that fails a test
when a command starts its work (loads a model) although it should have refused first, robot
configs whose default serial ports do not exist."""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest


@pytest.fixture
def read_only_dir(tmp_path: Path) -> Iterator[Path]:
    """An existing folder this process cannot create files in: mode 0555, or, for root (who
    ignores modes), the immutable attribute (skips where neither works)."""
    folder = tmp_path / "read_only"
    folder.mkdir()
    if os.geteuid() != 0:
        folder.chmod(0o555)
        undo = ["chmod", "755", str(folder)]
    else:
        chattr = shutil.which("chattr")
        done = chattr is not None and subprocess.run([chattr, "+i", str(folder)]).returncode == 0
        if chattr is None or not done:
            pytest.skip("running as root without chattr +i: cannot make a read-only folder")
        undo = [chattr, "-i", str(folder)]
    try:
        probe = folder / "probe"
        try:
            probe.touch()
        except OSError:
            pass
        else:
            probe.unlink()
            pytest.skip(f"{folder} is still writable here")
        yield folder
    finally:
        subprocess.run(undo, check=False)


@pytest.fixture
def no_work(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if the command gets as far as loading a model (its first real work)."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the command started its work before refusing its arguments")

    monkeypatch.setattr("robot_retarget.nn.inference.load_model", refuse)


@pytest.fixture
def missing_default_ports(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """Robot configs loaded by name get each bus's ``default_port`` at ``tmp/tty_<bus>``, a path
    that does not exist; returns ``tmp``."""
    import robot_retarget.robot.loader as loader

    real = loader.load_robot_config

    def missing_defaults(name: str) -> object:
        config = real(name)
        buses = tuple(
            dataclasses.replace(b, default_port=str(tmp_path / f"tty_{b.name}"))
            for b in config.buses
        )
        return dataclasses.replace(config, buses=buses)

    monkeypatch.setattr(loader, "load_robot_config", missing_defaults)
    return tmp_path
