"""Fixtures for the dataset / training / inference tests: a tiny mocap folder made of the
project's own fixture clips (three subjects), and one torch thread."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
import torch

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"

# subject folder → fixture clips (12–24 frames each, 24–30 fps)
TINY_SUBJECTS: dict[str, tuple[str, ...]] = {
    "s1": ("tiny_walk.bvh", "asf_names.bvh"),
    "s2": ("mixamo.bvh", "y_up_reference.bvh"),
    "s3": ("crlf_tabs.bvh",),
}


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def make_mocap_dir(root: Path) -> Path:
    """Copy the fixture clips into ``root/<subject>/``; returns ``root``."""
    for subject, files in TINY_SUBJECTS.items():
        (root / subject).mkdir(parents=True, exist_ok=True)
        for name in files:
            shutil.copy(FIXTURES / name, root / subject / name)
    return root


@pytest.fixture
def mocap_dir(tmp_path: Path) -> Path:
    return make_mocap_dir(tmp_path / "mocap")


@pytest.fixture
def cache_dir(tmp_path: Path) -> Path:
    return tmp_path / "cache"
