"""Suite-wide fixtures: where the shared data lives, the hypothesis profile, and a deadline
for every test."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

import pytest
from hypothesis import settings

# No per-example deadline (2 shared cores make timings noisy); fixed examples on CI so a red
# build reproduces locally with CI=1.
settings.register_profile("ci", deadline=None, derandomize=bool(os.environ.get("CI")))
settings.load_profile("ci")

# A suite started in the background by a non-interactive shell inherits SIGINT ignored, and
# Python (with every child process it starts) keeps it so: the Ctrl-C tests need it live.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

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


DEFAULT_TIME_LIMIT_S = 120


@pytest.fixture(autouse=True)
def _time_limit(request: pytest.FixtureRequest) -> Iterator[None]:
    """Fail, never hang: a test running past its module's ``TIME_LIMIT_S`` (default
    DEFAULT_TIME_LIMIT_S) raises TimeoutError. Tests with serial ports, sockets and threads
    must not be able to stall CI."""
    if not hasattr(signal, "SIGALRM"):
        yield
        return
    seconds = int(getattr(request.module, "TIME_LIMIT_S", DEFAULT_TIME_LIMIT_S))

    def _expire(signum: int, frame: FrameType | None) -> None:
        raise TimeoutError(f"test exceeded its {seconds} s time limit")

    old = signal.signal(signal.SIGALRM, _expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
