"""Fixtures of the viewer tests: a headless Chromium (skipped, with the reason, without one)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from robot_retarget.viewer.chromium import find_chromium
from tests.viewer.chromium import HeadlessChromium


@pytest.fixture
def chromium(tmp_path: Path) -> Iterator[HeadlessChromium]:
    pytest.importorskip("viser", reason="the viewer needs the [view] extra (pip install viser)")
    executable = find_chromium()
    if executable is None:
        pytest.skip("Chromium not found: apt-get install chromium (or set ROBOT_RETARGET_CHROMIUM)")
    browser = HeadlessChromium(executable, tmp_path / "chromium-profile")
    try:
        yield browser
    finally:
        browser.close()
