"""The SDK fixes: stuffed Protocol 2.0 transmit, short packet timeouts, float protocol."""

from __future__ import annotations

import dynamixel_sdk as sdk
import pytest

from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.sdk import (
    StuffedProtocol2PacketHandler,
    TimedPortHandler,
    packet_handler,
)


class _CapturePort:
    """Just enough of PortHandler for txPacket."""

    def __init__(self) -> None:
        self.is_using = False
        self.written = b""

    def clearPort(self) -> None:
        pass

    def writePort(self, packet: bytes | list[int]) -> int:
        self.written = bytes(packet)
        return len(self.written)


def test_sdk_sends_unstuffed_packets_and_we_do_not() -> None:
    goal = -131073  # little endian FF FF FD FF
    stock, fixed = _CapturePort(), _CapturePort()
    sdk.Protocol2PacketHandler().writeTxOnly(stock, 1, 116, 4, list(p.le_bytes(goal, 4)))
    StuffedProtocol2PacketHandler().writeTxOnly(fixed, 1, 116, 4, list(p.le_bytes(goal, 4)))
    with pytest.raises(p.MalformedPacketError):
        p.parse_v2(stock.written)  # the SDK bug DESIGN.md describes
    pkt = p.parse_v2(fixed.written)
    assert pkt.params == p.le_bytes(116, 2) + p.le_bytes(goal, 4)
    assert len(fixed.written) == len(stock.written) + 1


def test_unaffected_packets_are_identical_to_the_sdk() -> None:
    stock, fixed = _CapturePort(), _CapturePort()
    sdk.Protocol2PacketHandler().writeTxOnly(stock, 7, 116, 4, [0, 8, 0, 0])
    StuffedProtocol2PacketHandler().writeTxOnly(fixed, 7, 116, 4, [0, 8, 0, 0])
    assert fixed.written == stock.written


def test_packet_handler_takes_the_float() -> None:
    assert packet_handler(1.0).getProtocolVersion() == 1.0
    assert packet_handler(2).getProtocolVersion() == 2.0
    with pytest.raises(ValueError, match=r"1\.0 or 2\.0"):
        packet_handler(3.0)


def test_timed_port_handler_timeout_is_wire_time_plus_margin() -> None:
    port = TimedPortHandler("/dev/null", packet_timeout_ms=3.0)
    port.tx_time_per_byte = 10.0 / 2_000_000 * 1000.0  # ms per byte at 2 Mbps
    port.setPacketTimeout(100)
    assert port.packet_timeout == pytest.approx(0.5 + 3.0)
    stock = sdk.PortHandler("/dev/null")
    stock.tx_time_per_byte = port.tx_time_per_byte
    stock.setPacketTimeout(100)
    assert stock.packet_timeout > 30.0  # the SDK default we avoid
