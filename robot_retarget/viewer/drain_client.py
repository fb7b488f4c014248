"""A page watcher without a browser: ``python -m robot_retarget.viewer.drain_client URL``.

Connects to a viewer's websocket as viser's own web client does and reads every message until
the server goes away or the process is stopped, so the server does all the work of a watched
page (serialising and sending every update) without a renderer. ``bench stream --view``
runs it in its own process, as a browser would be. Prints ``messages bytes`` at the end.
"""

from __future__ import annotations

import signal
import sys
from types import FrameType


def drain(url: str) -> tuple[int, int]:
    """Read messages from the viewer at ``url`` (http:// or ws://) until it closes."""
    import viser
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect
    from websockets.typing import Subprotocol

    ws_url = "ws://" + url.split("://", 1)[-1]
    messages = size = 0
    protocol = Subprotocol(f"viser-v{viser.__version__}")  # viser refuses other versions
    with connect(ws_url, subprotocols=[protocol], max_size=None, open_timeout=10) as ws:
        print("connected", flush=True)  # a caller may wait for this line
        try:
            while True:
                data = ws.recv()
                messages += 1
                size += len(data)
        except (ConnectionClosed, KeyboardInterrupt):
            pass
    return messages, size


def _stop(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python -m robot_retarget.viewer.drain_client URL", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, _stop)
    messages, size = drain(argv[0])
    print(messages, size, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
