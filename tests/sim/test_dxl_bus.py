"""The simulated bus, driven by the unmodified dynamixel-sdk over the pty (and by raw bytes)."""

from __future__ import annotations

from typing import Any

import dynamixel_sdk as sdk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.sim.dxl_bus import SimulatedBus
from robot_retarget.sim.servo import SimServo

Client = tuple[Any, Any]
OK = sdk.COMM_SUCCESS


def test_ping_and_broadcast_ping_v2(v2_client: Client) -> None:
    port, ph = v2_client
    assert ph.ping(port, 5) == (1020, OK, 0)
    assert ph.ping(port, 9)[1] == sdk.COMM_RX_TIMEOUT
    found, result = ph.broadcastPing(port)
    assert result == OK
    assert sorted(found) == [1, 2, 5]


def test_read_write_and_eeprom_lock_v2(v2_client: Client, v2_bus: SimulatedBus) -> None:
    port, ph = v2_client
    assert ph.write1ByteTxRx(port, 2, 11, 4) == (OK, 0)  # operating mode, torque off: fine
    assert ph.write1ByteTxRx(port, 2, 64, 1) == (OK, 0)  # torque on
    result, error = ph.write1ByteTxRx(port, 2, 11, 3)
    assert result == OK
    assert error == p.ERR2_ACCESS
    assert v2_bus.servos[2].get("operating_mode") == 4
    assert ph.write4ByteTxRx(port, 2, 132, 0)[1] == p.ERR2_ACCESS  # read-only register
    assert ph.write1ByteTxRx(port, 2, 116, 0)[1] == p.ERR2_DATA_LENGTH  # half a register
    assert ph.read4ByteTxRx(port, 2, 116) == (2048, OK, 0)


def test_goal_outside_position_limits_is_a_data_limit_error(v2_client: Client) -> None:
    port, ph = v2_client
    assert ph.write4ByteTxRx(port, 1, 116, 5000) == (OK, p.ERR2_DATA_LIMIT)
    assert ph.read4ByteTxRx(port, 1, 116)[0] == 2048


def test_reg_write_and_action(v2_client: Client, v2_bus: SimulatedBus) -> None:
    port, ph = v2_client
    assert ph.regWriteTxRx(port, 1, 116, 4, list(p.le_bytes(1500, 4))) == (OK, 0)
    assert v2_bus.servos[1].get("goal_position") == 2048
    assert v2_bus.servos[1].get("registered_instruction") == 1
    assert ph.action(port, sdk.BROADCAST_ID) == OK
    v2_bus.settle()
    assert v2_bus.servos[1].get("goal_position") == 1500


def test_sync_and_fast_sync_read_and_bulk_v2(v2_client: Client, v2_bus: SimulatedBus) -> None:
    port, ph = v2_client
    gsw = sdk.GroupSyncWrite(port, ph, 116, 4)
    for sid, goal in ((1, 100), (2, 200), (5, 300)):
        gsw.addParam(sid, list(p.le_bytes(goal, 4)))
    assert gsw.txPacket() == OK
    gsr = sdk.GroupSyncRead(port, ph, 116, 4)
    for sid in (1, 2, 5):
        gsr.addParam(sid)
    assert gsr.txRxPacket() == OK
    assert [gsr.getData(s, 116, 4) for s in (1, 2, 5)] == [100, 200, 300]
    assert gsr.fastSyncRead() == OK
    assert [gsr.getData(s, 116, 4) for s in (1, 2, 5)] == [100, 200, 300]
    gbw = sdk.GroupBulkWrite(port, ph)
    gbw.addParam(1, 65, 1, [1])  # LED
    gbw.addParam(5, 116, 4, list(p.le_bytes(400, 4)))
    assert gbw.txPacket() == OK
    gbr = sdk.GroupBulkRead(port, ph)
    gbr.addParam(1, 65, 1)
    gbr.addParam(5, 116, 4)
    assert gbr.txRxPacket() == OK
    assert (gbr.getData(1, 65, 1), gbr.getData(5, 116, 4)) == (1, 400)


def test_hardware_error_bit_and_reboot(v2_client: Client, v2_bus: SimulatedBus) -> None:
    port, ph = v2_client
    assert ph.write1ByteTxRx(port, 2, 64, 1) == (OK, 0)
    v2_bus.servos[2].inject_hardware_error(0x20)
    _model, result, error = ph.ping(port, 2)
    assert result == OK
    assert error & p.ERR2_ALERT
    assert ph.read1ByteTxRx(port, 2, 70)[0] == 0x20
    assert ph.read1ByteTxRx(port, 2, 64)[0] == 0  # shutdown: torque off
    assert ph.reboot(port, 2) == (OK, p.ERR2_ALERT)  # answers, then reboots
    v2_bus.settle()
    assert ph.ping(port, 2) == (1020, OK, 0)


def test_protocol1_instructions(v1_client: Client, v1_bus: SimulatedBus) -> None:
    port, ph = v1_client
    assert ph.ping(port, 13) == (310, OK, 0)
    assert ph.ping(port, 36) == (12, OK, 0)
    assert ph.write2ByteTxRx(port, 11, 30, 1000) == (OK, 0)
    assert ph.read2ByteTxRx(port, 11, 30) == (1000, OK, 0)
    assert ph.write2ByteTxRx(port, 36, 30, 2000) == (OK, p.ERR1_ANGLE_LIMIT)  # AX: 0–1023
    assert ph.write1ByteTxRx(port, 11, 24, 1) == (OK, 0)
    # Protocol 1.0 servos take EEPROM writes with torque on (only Lock = 1 refuses them).
    assert ph.write1ByteTxRx(port, 11, 5, 0) == (OK, 0)
    assert ph.read1ByteTxRx(port, 11, 5) == (0, OK, 0)
    gsw = sdk.GroupSyncWrite(port, ph, 30, 2)
    gsw.addParam(13, [0x10, 0x01])
    gsw.addParam(36, [0x00, 0x01])
    assert gsw.txPacket() == OK
    v1_bus.settle()
    assert v1_bus.servos[13].get("goal_position") == 0x110
    assert v1_bus.servos[36].get("goal_position") == 0x100
    gbr = sdk.GroupBulkRead(port, ph)
    gbr.addParam(11, 36, 2)
    with pytest.raises(TypeError):  # the SDK bug the backend works around
        gbr.txRxPacket()


def test_protocol1_bulk_read_raw_and_error_bits(v1_bus: SimulatedBus) -> None:
    req = p.build_v1(p.BROADCAST_ID, p.INST_BULK_READ, bytes((0, 2, 11, 30, 2, 13, 30, 2, 36, 30)))
    v1_bus.servos[13].inject_hardware_error(p.ERR1_OVERHEATING)
    out = v1_bus.feed(req)
    first = p.parse_v1(out[:8], status=True)
    second = p.parse_v1(out[8:16], status=True)
    assert (first.servo_id, first.code, p.from_le(first.params)) == (11, 0, 2048)
    assert (second.servo_id, second.code) == (13, p.ERR1_OVERHEATING)
    assert len(out) == 16  # the AX ignores bulk read


def test_crc_error_reply_and_strict_stuffing(v2_bus: SimulatedBus) -> None:
    raw = bytearray(p.build_v2(1, p.INST_PING))
    raw[-1] ^= 0xFF
    reply = p.parse_v2(v2_bus.feed(bytes(raw)))
    assert reply.code == p.ERR2_CRC
    # An unstuffed FF FF FD in a payload is malformed: rejected, no reply, nothing written.
    region = bytes((p.INST_WRITE,)) + p.le_bytes(20, 2) + b"\xff\xff\xfd\xff"
    head = p.HEADER_V2 + bytes((1, len(region) + 2, 0)) + region
    crc = p.crc16(head)
    assert v2_bus.feed(head + bytes((crc & 0xFF, crc >> 8))) == b""
    assert "stuffing" in v2_bus.log.rejected[-1][1]
    assert v2_bus.servos[1].get("homing_offset") == 0
    # The same write, stuffed, is accepted.
    ok = v2_bus.feed(p.build_v2(1, p.INST_WRITE, p.le_bytes(20, 2) + b"\xff\xff\xfd\xff"))
    assert p.parse_v2(ok).code == 0
    assert v2_bus.servos[1].get("homing_offset") == -131073


def test_unknown_instruction_and_garbage(v2_bus: SimulatedBus) -> None:
    assert p.parse_v2(v2_bus.feed(p.build_v2(5, 0x77))).code == p.ERR2_INSTRUCTION
    assert v2_bus.feed(b"\x00\x13\x37") == b""  # noise before a header is skipped
    assert p.parse_v2(v2_bus.feed(p.build_v2(5, p.INST_PING))).servo_id == 5


def test_wire_time_model_delays_replies() -> None:
    """The reply is ready when the request and 20 replies would have crossed a 57.6 kbps wire
    (10 bits a byte, return delay 0): judged on the bus's own clock, not the wall clock."""
    ticks = iter(range(10**9))

    def clock() -> float:  # 1 µs per reading: spins end, nothing waits for real time
        return next(ticks) * 1e-6

    servos = [SimServo(i, "XM430-W350") for i in range(1, 21)]
    bus = SimulatedBus(servos, protocol=2.0, baud_rate=57_600, wire_time=True, clock=clock)
    for s in servos:
        s._put("return_delay_time", 0)
    request = p.build_v2(p.BROADCAST_ID, p.INST_SYNC_READ, bytes([132, 0, 4, 0, *range(1, 21)]))
    t0 = clock()
    replies = bus.feed(request)
    assert replies.count(p.HEADER_V2) == 20
    wire_s = (len(request) + len(replies)) * 10 / 57_600  # 34 + 20 × 15 bytes
    assert bus._bus_free_at - t0 == pytest.approx(wire_s, abs=1e-4)


def test_fault_injection(v2_client: Client, v2_bus: SimulatedBus) -> None:
    port, ph = v2_client
    v2_bus.faults.drop_replies = 1
    assert ph.ping(port, 1)[1] == sdk.COMM_RX_TIMEOUT
    v2_bus.faults.corrupt_replies = 1
    assert ph.ping(port, 1)[1] == sdk.COMM_RX_CORRUPT
    v2_bus.faults.only_id, v2_bus.faults.drop_replies = 5, 1
    assert ph.ping(port, 1)[1] == OK  # only ID 5 is affected
    assert ph.ping(port, 5)[1] == sdk.COMM_RX_TIMEOUT
    v2_bus.faults.only_id = None
    v2_bus.faults.late_replies, v2_bus.faults.late_reply_s = 1, 0.1
    assert ph.ping(port, 2)[1] == sdk.COMM_RX_TIMEOUT  # SDK timeout ≈ 34 ms < 100 ms


def test_unplug_gives_io_errors_not_hangs(v2_client: Client, v2_bus: SimulatedBus) -> None:
    port, ph = v2_client
    v2_bus.unplug()
    with pytest.raises(Exception, match=r"Input/output|read failed|readiness"):
        ph.ping(port, 1)  # (a hang would trip the suite's per-test time limit)


def test_mixed_protocols_are_refused() -> None:
    with pytest.raises(ValueError, match="Protocol"):
        SimulatedBus([SimServo(1, "MX-28")], protocol=2.0)
    with pytest.raises(ValueError, match=r"1\.0 or 2\.0"):
        SimulatedBus([], protocol=3.0)


def test_back_to_back_packets_in_one_read(v2_bus: SimulatedBus) -> None:
    out = v2_bus.feed(p.build_v2(1, p.INST_PING) + p.build_v2(5, p.INST_PING))
    first = p.parse_v2(out[:14])
    second = p.parse_v2(out[14:])
    assert (first.servo_id, second.servo_id) == (1, 5)


def test_partial_packet_waits_for_the_rest(v2_bus: SimulatedBus) -> None:
    raw = p.build_v2(2, p.INST_PING)
    assert v2_bus.feed(raw[:5]) == b""
    assert p.parse_v2(v2_bus.feed(raw[5:])).servo_id == 2


@settings(max_examples=150)
@given(st.lists(st.integers(-1_048_575, 1_048_575), min_size=3, max_size=3))
def test_any_extended_goal_survives_stuffing(goals: list[int]) -> None:
    servos = [SimServo(i, "XM430-W350") for i in (1, 2, 3)]
    for s in servos:
        s._put("operating_mode", 4)
    bus = SimulatedBus(servos, protocol=2.0)
    client = DynamixelBus("unused", protocol=2.0, baud_rate=1_000_000)
    packet = client.sync_write_packet(
        116, 4, {sid: p.le_bytes(g, 4) for sid, g in zip((1, 2, 3), goals, strict=True)}
    )
    assert bus.feed(packet) == b""
    assert not bus.log.rejected
    assert [s.get("goal_position") for s in servos] == goals


def test_a_protocol_1_bulk_read_chain_stops_at_a_servo_that_cannot_answer() -> None:
    """MX e-Manual: each module answers after the one listed before it, so an AX (no Bulk
    Read) or a missing ID in the list ends the chain; the ones after it stay silent."""
    servos = [SimServo(11, "MX-28"), SimServo(36, "AX-12A"), SimServo(13, "MX-64")]
    bus = SimulatedBus(servos, protocol=1.0, baud_rate=1_000_000)
    # Bulk Read params: 0x00, then (length, id, address) per servo: present position (36, 2 B).
    params = bytes([0x00, 2, 11, 36, 2, 36, 36, 2, 13, 36])
    replies = bus.feed(p.build_v1(p.BROADCAST_ID, p.INST_BULK_READ, params))
    assert replies.count(b"\xff\xff") == 1  # 11 answers; 36 cannot, so 13 never does
    assert replies[2] == 11
    params = bytes([0x00, 2, 11, 36, 2, 13, 36])
    assert bus.feed(p.build_v1(p.BROADCAST_ID, p.INST_BULK_READ, params)).count(b"\xff\xff") == 2


def test_a_usb2ax_bus_answers_sync_read_in_one_packet_from_the_adapter() -> None:
    servos = [SimServo(11, "MX-28"), SimServo(13, "MX-64")]
    request = p.build_v1(p.BROADCAST_ID, 0x84, bytes([36, 2, 11, 13]))  # present position ×2
    plain = SimulatedBus(servos, protocol=1.0, baud_rate=1_000_000)
    assert plain.feed(request) == b""  # a bare MX bus has no Sync Read: silence
    usb2ax = SimulatedBus(servos, protocol=1.0, baud_rate=1_000_000, usb2ax=True)
    reply = p.parse_v1(usb2ax.feed(request), status=True)
    assert reply.servo_id == 0xFD
    assert reply.params == servos[0].read(36, 2)[1] + servos[1].read(36, 2)[1]
    missing = p.build_v1(p.BROADCAST_ID, 0x84, bytes([36, 2, 11, 99]))
    assert usb2ax.feed(missing) == b""  # a servo that does not answer: a timeout


def test_fast_bulk_read_answers_in_one_packet_with_running_crcs() -> None:
    """Protocol 2.0 Fast Bulk Read (0x9A): each servo's own address and length, one reply."""
    servos = [SimServo(1, "XM430-W350"), SimServo(2, "XM430-W350")]
    bus = SimulatedBus(servos, protocol=2.0, baud_rate=2_000_000)
    items = [(1, 132, 4), (2, 126, 2)]  # present position; present load
    params = b"".join(bytes([i]) + a.to_bytes(2, "little") + n.to_bytes(2, "little")
                      for i, a, n in items)  # fmt: skip
    reply = bus.feed(p.build_v2(p.BROADCAST_ID, p.INST_FAST_BULK_READ, params))
    packet = p.parse_v2(reply)  # the whole packet's CRC is checked here
    assert packet.servo_id == p.BROADCAST_ID
    body = packet.params  # after the first ERR: ID DATA CRC, ERR ID DATA (CRC: the packet's)
    assert body[0] == 1
    assert body[1:5] == servos[0].read(132, 4)[1]
    assert body[5:7] == p.crc16(reply[:14]).to_bytes(2, "little")  # running CRC
    assert body[8] == 2
    assert body[9:11] == servos[1].read(126, 2)[1]
    servos[1]._put("firmware_version", 44)  # before Fast Bulk Read: the chain is cut short
    cut = bus.feed(p.build_v2(p.BROADCAST_ID, p.INST_FAST_BULK_READ, params))
    assert 0 < len(cut) < len(reply)
    servos[0]._put("firmware_version", 44)
    assert bus.feed(p.build_v2(p.BROADCAST_ID, p.INST_FAST_BULK_READ, params)) == b""


def test_the_sdks_unstuffed_packet_gets_no_reply_and_a_stuffed_one_does(
    v2_client: Client, v2_bus: SimulatedBus
) -> None:
    """dynamixel-sdk sends FF FF FD in a payload without the stuffing FD: malformed, so no
    status at all (the client times out) and nothing written; the backend's bus stuffs it."""
    port, ph = v2_client
    offset = -131073  # little endian FF FF FD FF
    result, _error = ph.write4ByteTxRx(port, 1, 20, offset & 0xFFFFFFFF)
    assert result == sdk.COMM_RX_TIMEOUT
    v2_bus.settle()
    assert v2_bus.servos[1].get("homing_offset") == 0
    assert "stuffing" in v2_bus.log.rejected[-1][1]
    port.closePort()
    bus = DynamixelBus(v2_bus.port or "", protocol=2.0, baud_rate=2_000_000,
                       packet_timeout_ms=20.0)  # fmt: skip
    bus.open()
    try:
        assert bus.write(1, 20, p.le_bytes(offset, 4)) == 0
    finally:
        bus.close()
    assert v2_bus.servos[1].get("homing_offset") == offset


def test_goals_outside_the_angle_limits_are_refused_and_silently_under_sync_write(
    v1_client: Client, v1_bus: SimulatedBus
) -> None:
    """Limits pypot left (here 1800 … 2300): a direct write answers with the Angle Limit bit
    and keeps the old goal; a Sync Write has no status, so the goal is just not taken."""
    port, ph = v1_client
    servo = v1_bus.servos[11]
    servo._put("cw_angle_limit", 1800)
    servo._put("ccw_angle_limit", 2300)
    assert ph.write2ByteTxRx(port, 11, 30, 2500) == (OK, p.ERR1_ANGLE_LIMIT)
    assert servo.get("goal_position") == 2048
    gsw = sdk.GroupSyncWrite(port, ph, 30, 2)
    gsw.addParam(11, list(p.le_bytes(1700, 2)))
    gsw.addParam(13, list(p.le_bytes(1700, 2)))
    assert gsw.txPacket() == OK
    v1_bus.settle()
    assert servo.get("goal_position") == 2048  # refused, and nobody heard
    assert v1_bus.servos[13].get("goal_position") == 1700
