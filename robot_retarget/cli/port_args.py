"""``--port``: one syntax for every command that opens a Dynamixel bus (``stream``, ``doctor``).

- ``--port PATH`` for a one-bus robot (OP3);
- ``--port BUS=PATH``, repeatable, one per bus, naming the robot config's bus (Poppy:
  ``--port upper_body=/dev/ttyACM0 --port lower_body=/dev/ttyACM1``).

``stream`` opens a bus not named at the config's ``default_port``; ``doctor`` checks only the buses
named (every bus, at its default port, without ``--port``). The items are matched against the robot
config by :func:`robot_retarget.pipeline.backends.parse_ports` (unknown bus names and a plain PATH
on a robot with several buses are refused there). :func:`check_ports_exist` refuses a device path
that does not exist before any work starts.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence

from robot_retarget.errors import HardwareError

PORT_HELP = (
    "serial port: PATH for a one-bus robot, or BUS=PATH naming one of the config's buses "
    "(repeatable, once per bus)"
)


class PortNotFoundError(HardwareError):
    """A serial port given on the command line does not exist. ``port`` is the path,
    ``available`` the ports the OS lists (may be empty)."""

    def __init__(
        self, port: str, available: Sequence[str] = (), *, problem: str = "does not exist"
    ) -> None:
        self.port = port
        self.available = tuple(available)
        self.problem = problem
        hint = (
            f"ports found: {', '.join(self.available)}"
            if self.available
            else "no serial ports found: is the adapter plugged in?"
        )
        super().__init__(f"serial port {port} {problem} ({hint}); check --port")


def add_port_argument(parser: argparse.ArgumentParser, omitted: str = "") -> None:
    """``--port [BUS=]PATH``, repeatable; the list lands in ``args.port``. ``omitted``: what the
    command does for a bus no ``--port`` names, added to the help."""
    help_text = f"{PORT_HELP}; {omitted}" if omitted else PORT_HELP
    parser.add_argument("--port", action="append", default=[], metavar="[BUS=]PATH", help=help_text)


def split_port(item: str) -> tuple[str | None, str]:
    """``"BUS=PATH"`` → (BUS, PATH); ``"PATH"`` → (None, PATH)."""
    bus, sep, path = item.partition("=")
    return (bus, path) if sep else (None, item)


def _is_device_path(path: str) -> bool:
    """A path we can check for existence: not a pyserial URL (``rfc2217://…``), not a Windows
    COM name."""
    return "://" not in path and os.name != "nt"


def check_ports_exist(items: Sequence[str], available: Sequence[str] | None = None) -> None:
    """Raise :class:`PortNotFoundError` for the first ``[BUS=]PATH`` whose PATH is missing or
    a folder; ``available``: the ports the OS lists (listed here when not given)."""
    for item in items:
        _, path = split_port(item)
        if not _is_device_path(path):
            continue
        problem = (
            "does not exist" if not os.path.exists(path)
            else "is a folder, not a serial port" if os.path.isdir(path)
            else None
        )  # fmt: skip
        if problem is not None:
            if available is None:
                from robot_retarget.hardware.doctor import serial_ports

                available = [info.device for info in serial_ports()]
            raise PortNotFoundError(path, available, problem=problem)
