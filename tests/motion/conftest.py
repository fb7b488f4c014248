"""Fixtures for the motion tests: the hand-made BVH files and the shared CMU clips."""

from __future__ import annotations

from pathlib import Path

import pytest

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"


@pytest.fixture(scope="session")
def motion_fixtures() -> Path:
    """tests/fixtures/motion (small BVH files written for these tests)."""
    return FIXTURES


@pytest.fixture(scope="session")
def mocap_dir(shared_data_dir: Path) -> Path:
    """The shared CMU BVH clips; skips when they are absent."""
    path = shared_data_dir / "mocap"
    if not path.is_dir():
        pytest.skip(f"no mocap folder in the shared data ({path})")
    return path


@pytest.fixture(scope="session")
def mocap_clips(mocap_dir: Path) -> list[Path]:
    """All 70 clips, sorted by name."""
    clips = sorted(mocap_dir.glob("*/*.bvh"))
    if not clips:
        pytest.skip(f"no BVH clips under {mocap_dir}")
    return clips
