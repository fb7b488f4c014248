"""Fixes around dynamixel-sdk 4.1.0, kept in one place.

- :class:`TimedPortHandler`: the SDK's packet timeout is wire time + 2 × 16 ms (FTDI latency
  timer) + 2 ms ≈ 34 ms; we use wire time + a configurable margin (a few ms) so a missing reply
  costs milliseconds, not a frame.
- :class:`StuffedProtocol2PacketHandler`: the SDK's Protocol 2.0 ``txPacket`` calls
  ``addStuffing`` and drops its result, so packets whose payload holds ``FF FF FD`` go out
  malformed. This handler builds every packet with :mod:`robot_retarget.hardware.protocol`
  (stuffed, CRC after stuffing); all SDK helpers (ping, read, write, GroupSync*) then send
  correct bytes.
- ``PacketHandler("1.0")`` silently gives Protocol 2.0: :func:`packet_handler` takes the float.
"""

from __future__ import annotations

from typing import Any

import dynamixel_sdk as sdk

from robot_retarget.hardware import protocol as p


class TimedPortHandler(sdk.PortHandler):  # type: ignore[misc]
    """PortHandler with packet timeout = bytes × 10 bits / baud + ``packet_timeout_ms``."""

    def __init__(self, port_name: str, packet_timeout_ms: float = 4.0) -> None:
        super().__init__(port_name)
        self.packet_timeout_ms = float(packet_timeout_ms)

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.packet_timeout_ms


class StuffedProtocol2PacketHandler(sdk.Protocol2PacketHandler):  # type: ignore[misc]
    """Protocol 2.0 handler whose transmit applies byte stuffing correctly."""

    def txPacket(self, port: Any, txpacket: list[int]) -> int:
        if port.is_using:
            return sdk.COMM_PORT_BUSY
        port.is_using = True
        length = txpacket[5] | (txpacket[6] << 8)  # unstuffed: INST + PARAMS + CRC
        params = bytes(txpacket[8 : 8 + length - 3])
        packet = p.build_v2(txpacket[4], txpacket[7], params)
        if len(packet) > 1024:
            port.is_using = False
            return sdk.COMM_TX_ERROR
        port.clearPort()
        if port.writePort(packet) != len(packet):
            port.is_using = False
            return sdk.COMM_TX_FAIL
        return sdk.COMM_SUCCESS


def packet_handler(protocol: float) -> Any:
    """The SDK packet handler for ``protocol`` (1.0 or 2.0, as a number)."""
    if float(protocol) == 2.0:
        return StuffedProtocol2PacketHandler()
    if float(protocol) == 1.0:
        return sdk.PacketHandler(1.0)
    raise ValueError(f"Dynamixel protocol must be 1.0 or 2.0, got {protocol!r}")
