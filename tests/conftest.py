"""Suite-wide fixtures: where the shared data lives, and the hypothesis profile."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

# No per-example deadline (2 shared cores make timings noisy); fixed examples on CI so a red
# build reproduces locally with CI=1.
settings.register_profile("ci", deadline=None, derandomize=bool(os.environ.get("CI")))
settings.load_profile("ci")

_DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data_dir() -> Path:
    """$ROBOT_RETARGET_DATA, else <repo>/../shared/data; skips the test when absent."""
    path = Path(os.environ.get("ROBOT_RETARGET_DATA", _DEFAULT_DATA))
    if not path.is_dir():
        pytest.skip(
            f"shared data not found at {path}: set ROBOT_RETARGET_DATA to the data folder "
            "(mocap/, robots/)"
        )
    return path
