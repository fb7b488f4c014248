"""Headless Chromium driven over the DevTools protocol, for the viewer's browser test.

Chromium is the Debian package (``apt-get install chromium``); it is found on the PATH or at
$ROBOT_RETARGET_CHROMIUM, and the tests that need it skip with the reason when it is not. The
protocol is spoken over a plain websocket (the ``websockets`` client viser already brings), so
no browser-automation package is needed.
"""

from __future__ import annotations

import base64
import io
import itertools
import json
import subprocess
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.viewer.chromium import HEADLESS_FLAGS

CHROMIUM_FLAGS = (*HEADLESS_FLAGS, "--remote-debugging-port=0")
WINDOW = (1200, 800)


class HeadlessChromium:
    """One headless Chromium with one page, screenshots as RGB arrays."""

    def __init__(self, executable: str, profile: Path, *, start_timeout_s: float = 30.0) -> None:
        from websockets.sync.client import connect

        self._proc = subprocess.Popen(
            [
                executable,
                *CHROMIUM_FLAGS,
                f"--user-data-dir={profile}",
                f"--window-size={WINDOW[0]},{WINDOW[1]}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + start_timeout_s
        while not (port_file.is_file() and port_file.read_text().strip()):
            if self._proc.poll() is not None or time.monotonic() > deadline:
                self.close()
                raise RuntimeError(f"Chromium did not start (exit code {self._proc.returncode})")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            targets = json.loads(r.read())
        page = next(t for t in targets if t.get("type") == "page")
        self._ws = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=10)
        self._ids = itertools.count(1)

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """Send one DevTools command and return its result (events in between are skipped)."""
        msg_id = next(self._ids)
        self._ws.send(json.dumps({"id": msg_id, "method": method, "params": params}))
        while True:
            reply = json.loads(self._ws.recv(timeout=30))
            if reply.get("id") == msg_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return dict(reply.get("result", {}))

    def open(self, url: str, *, timeout_s: float = 30.0) -> None:
        """Navigate and wait for the page's load event (the scene arrives later, over the
        viewer's websocket: callers poll screenshots for it)."""
        self.call("Page.enable")
        self.call("Page.navigate", url=url)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            event = json.loads(self._ws.recv(timeout=max(deadline - time.monotonic(), 0.1)))
            if event.get("method") == "Page.loadEventFired":
                return
        raise RuntimeError(f"{url} did not load within {timeout_s} s")

    def screenshot(self) -> FloatArray:
        """The page as an (H, W, 3) uint8 array."""
        from PIL import Image

        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def close(self) -> None:
        ws = getattr(self, "_ws", None)
        if ws is not None:
            ws.close()
        self._proc.terminate()
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
