"""Headless Chromium for looking at the viewer's page without a screen (``bench stream
--client chromium``, the browser tests): where to find it and the flags it runs with.

The flags keep a headless Chromium quiet on a machine with a closed network: no GPU, no
QUIC, no first-run page, and none of the background connections (updates, sync) it would
otherwise try at every start.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

CHROMIUM_ENV = "ROBOT_RETARGET_CHROMIUM"  # an explicit executable, else the PATH is searched
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
HEADLESS_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)


def find_chromium() -> str | None:
    """``$ROBOT_RETARGET_CHROMIUM`` when it names a file, else the first Chromium or Chrome
    on the PATH; None when there is none."""
    explicit = os.environ.get(CHROMIUM_ENV)
    if explicit:
        return explicit if Path(explicit).is_file() else None
    return next((p for p in map(shutil.which, CHROMIUM_NAMES) if p), None)
