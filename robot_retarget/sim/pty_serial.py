"""Third-party clients that flush the output buffer before every packet, on a simulated bus.

pypot (Poppy's own library) calls pyserial's ``flushOutput()`` before each packet. On a USB
adapter that is harmless: the driver has already handed the previous packet to the wire. On a
pseudo-terminal it is not: bytes a client wrote sit in the kernel's pty buffer until the
kernel's worker moves them to the simulator's side, and a flush in that window discards them —
so a write that needs no reply (Sync Write, torque enable) can vanish. Measured with pypot
5.0.2 on the simulated Poppy (40 rounds of torque on, goals, torque off): 50/80 torque
changes took effect with the simulator in the client's process, 77/80 with it in its own
process, and 50/80 with a ``cat`` process relaying the pty to the simulator as fast as the
kernel delivers: no simulator can read faster than the kernel moves pty bytes. With the flush
made a no-op on pseudo-terminals only, see the measurement in the README.

:func:`keep_pty_output` does exactly that, for the process that runs the client: pyserial's
``reset_output_buffer`` (what ``flushOutput`` calls) does nothing when the port is a
pseudo-terminal, and everything it did before on a real serial port. Use it when rehearsing a
pypot program against ``python -m robot_retarget.sim.dxl_bus``::

    from robot_retarget.sim.pty_serial import keep_pty_output
    keep_pty_output()
    import pypot.dynamixel
    ...
"""

from __future__ import annotations

import os
from typing import Any

_PTY_PREFIX = "/dev/pts/"
_installed = False


def is_pty(port: str | None) -> bool:
    """True for a pseudo-terminal path (what the simulated buses serve)."""
    if not port:
        return False
    try:
        return os.path.realpath(port).startswith(_PTY_PREFIX)
    except OSError:
        return False


def keep_pty_output() -> None:
    """Make pyserial's output flush a no-op on pseudo-terminals (idempotent)."""
    global _installed
    if _installed:
        return
    from serial import serialposix

    original = serialposix.Serial.reset_output_buffer

    def reset_output_buffer(self: Any) -> None:
        if is_pty(self.port):
            return  # nothing is "on the wire" to discard: the simulator reads it next
        original(self)

    serialposix.Serial.reset_output_buffer = reset_output_buffer
    _installed = True
