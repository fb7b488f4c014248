"""The bit rate a client set on a simulated bus's pseudo-terminal.

A pty carries bytes whatever its speed, but the client's speed setting is there to read: the
terminal settings belong to the device, so the simulator reads on its own end of the slave what
the client set on its end (pyserial, dynamixel-sdk). Standard rates come back as termios speed
constants; others (pyserial sets them with ``BOTHER`` through the Linux ``TCSETS2`` call) are
read back with ``TCGETS2``. None where the rate cannot be read (the bus then cannot tell).
"""

from __future__ import annotations

import fcntl
import struct
import sys
import termios

_SPEEDS: dict[int, int] = {}
for _name in dir(termios):
    if _name.startswith("B") and _name[1:].isdigit():
        _SPEEDS[int(getattr(termios, _name))] = int(_name[1:])

# Linux: struct termios2 is four tcflag_t, c_line, c_cc[19], then c_ispeed and c_ospeed.
_TCGETS2 = 0x802C542A
_BOTHER = 0o010000
_TERMIOS2 = struct.Struct("4IB19s2I")


def client_baud(fd: int) -> int | None:
    """The output speed set on terminal ``fd`` in bits per second, or None if unreadable."""
    try:
        speed = termios.tcgetattr(fd)[5]
    except (termios.error, OSError):
        return None
    if speed in _SPEEDS and speed != _BOTHER:
        return _SPEEDS[speed]
    if not sys.platform.startswith("linux"):
        return None
    try:
        raw = fcntl.ioctl(fd, _TCGETS2, bytes(_TERMIOS2.size))
    except OSError:
        return None
    ospeed = _TERMIOS2.unpack(raw)[-1]
    return int(ospeed) if ospeed > 0 else None
