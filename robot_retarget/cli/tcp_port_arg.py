"""``--port`` / ``--view-port`` for the browser viewer: a TCP port number, 0 for any free one."""

from __future__ import annotations

import argparse


def tcp_port_argument(text: str) -> int:
    """``"8080"`` → 8080; argparse's error for anything outside 0…65535 (0: any free port)."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number (0…65535)") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is not a port number (0…65535; 0: any free one)")
    return port
