"""What the simulated servos hear and answer, as real ones do: their baud rate, their ID
register, their Status Return Level; the instructions and register rules of the e-Manuals
(factory reset, clear, reboot, a unicast Protocol 1.0 Action, the shutdown); and no packet a
client sends stops the simulator."""

from __future__ import annotations

from typing import Any

import dynamixel_sdk as sdk
import pytest

from robot_retarget.hardware import protocol as p
from robot_retarget.sim.dxl_bus import USB2AX_SYNC_READ, SimulatedBus
from robot_retarget.sim.servo import SimServo

Client = tuple[Any, Any]
OK = sdk.COMM_SUCCESS
TIMEOUT = sdk.COMM_RX_TIMEOUT
le = p.le_bytes


def _replies_v2(raw: bytes) -> list[p.Packet]:
    out = []
    while raw:
        raw = raw[raw.find(p.HEADER_V2) :]
        n = p.packet_length_v2(raw)
        assert n is not None
        out.append(p.parse_v2(raw[:n]))
        raw = raw[n:]
    return out


def test_a_reply_too_long_for_a_packet_is_not_sent_and_the_bus_goes_on(
    v2_bus: SimulatedBus, v1_client: Client, v1_bus: SimulatedBus
) -> None:
    """A Fast Sync Read of 3 × 30000 bytes (the reply's length field holds 65535) and a USB2AX
    Sync Read of 4 × 70 bytes (a Protocol 1.0 packet holds 253) once killed the serving
    thread; now they get no reply, are logged, and the next packet is answered."""
    fast = p.build_v2(p.BROADCAST_ID, p.INST_FAST_SYNC_READ, le(0, 2) + le(30000, 2) + b"\1\2\5")
    assert v2_bus.feed(fast) == b""
    assert "does not fit one packet" in v2_bus.log.rejected[-1][1]
    assert [r.servo_id for r in _replies_v2(v2_bus.feed(p.build_v2(1, p.INST_PING, b"")))] == [1]
    port, ph = v1_client
    v1_bus.usb2ax = True
    long_read = p.build_v1(p.BROADCAST_ID, USB2AX_SYNC_READ, bytes((0, 70, 11, 13, 36, 11)))
    port.writePort(long_read)
    v1_bus.settle()
    assert "do not fit one Protocol 1.0 packet" in v1_bus.log.rejected[-1][1]
    assert ph.ping(port, 13) == (310, OK, 0)


@pytest.mark.parametrize("client", ["v2_client", "v1_client"])
def test_writing_the_id_moves_the_servo(client: str, request: pytest.FixtureRequest) -> None:
    """The reply comes from the ID addressed; after it the servo answers at its new ID only
    (LeRobot's motor setup writes the ID, then the baud rate at the new ID)."""
    port, ph = request.getfixturevalue(client)
    old = 5 if client == "v2_client" else 13
    address = 7 if client == "v2_client" else 3
    assert ph.write1ByteTxRx(port, old, address, 42) == (OK, 0)
    assert ph.ping(port, 42)[1:] == (OK, 0)
    assert ph.ping(port, old)[1] == TIMEOUT
    assert ph.read1ByteTxRx(port, 42, address) == (42, OK, 0)


def test_two_servos_on_one_id_answer_at_once(v2_client: Client, v2_bus: SimulatedBus) -> None:
    """Both act on a write to the shared ID; their replies collide into a corrupt packet."""
    port, ph = v2_client
    assert ph.write1ByteTxRx(port, 5, 7, 2) == (OK, 0)  # 5 → 2, where a servo already is
    assert ph.ping(port, 2)[1] != OK
    twins = [s for s in (*v2_bus.servos.values(), *v2_bus._twins) if s.servo_id == 2]
    assert len(twins) == 2
    ph.write1ByteTxRx(port, 2, 65, 1)  # LED on, both
    v2_bus.settle()
    assert [s.get("led") for s in twins] == [1, 1]


def test_a_servo_hears_only_a_client_at_its_baud_rate(v2_bus: SimulatedBus) -> None:
    """The bus's servos are set to its rate (Baud Rate 4 = 2 Mbps on an XM430); a client at
    57600 gets nothing; a servo moved to 1 Mbps answers there and no longer at 2 Mbps."""
    assert {s.get("baud_rate") for s in v2_bus.servos.values()} == {4}
    port = sdk.PortHandler(v2_bus.port)
    assert port.openPort()
    ph = sdk.PacketHandler(2.0)
    try:
        assert port.setBaudRate(57600)
        assert ph.ping(port, 1)[1] == TIMEOUT
        assert port.setBaudRate(2_000_000)
        assert ph.write1ByteTxRx(port, 1, 8, 3) == (OK, 0)  # answered at the old rate
        assert ph.ping(port, 1)[1] == TIMEOUT
        assert ph.ping(port, 2)[1:] == (OK, 0)
        assert port.setBaudRate(1_000_000)
        assert ph.ping(port, 1)[1:] == (OK, 0)
        assert ph.ping(port, 2)[1] == TIMEOUT
    finally:
        port.closePort()


@pytest.mark.parametrize("client", ["v2_client", "v1_client"])
def test_status_return_level(client: str, request: pytest.FixtureRequest) -> None:
    """0: a status for PING only; 1: for PING and READ; 2: for every instruction."""
    port, ph = request.getfixturevalue(client)
    sid, srl, led = (1, 68, 65) if client == "v2_client" else (11, 16, 25)
    torque = 64 if client == "v2_client" else 24
    if client == "v2_client":
        assert ph.write1ByteTxRx(port, sid, torque, 0) == (OK, 0)
    assert ph.write1ByteTxRx(port, sid, srl, 1) == (OK, 0)  # answered at the level before
    assert ph.read1ByteTxRx(port, sid, srl) == (1, OK, 0)
    assert ph.write1ByteTxRx(port, sid, led, 1)[0] == TIMEOUT  # written, not answered
    assert ph.read1ByteTxRx(port, sid, led) == (1, OK, 0)
    ph.write1ByteTxOnly(port, sid, srl, 0)
    assert ph.read1ByteTxRx(port, sid, led)[1] == TIMEOUT
    # PING is still answered (the SDK's Protocol 1.0 ping also reads the model number, which
    # a real servo at level 0 would not answer either: so the ping packet itself here).
    bus = request.getfixturevalue(client.replace("client", "bus"))
    build = p.build_v2 if client == "v2_client" else p.build_v1
    assert bus.feed(build(sid, p.INST_PING, b""))


def test_shutdown_keeps_torque_off_until_a_reboot_which_resets_the_ram(
    v2_client: Client, v2_bus: SimulatedBus
) -> None:
    port, ph = v2_client
    assert ph.write4ByteTxRx(port, 2, 112, 50) == (OK, 0)  # profile velocity (RAM)
    v2_bus.servos[2].inject_hardware_error(0x20)
    assert ph.write1ByteTxRx(port, 2, 64, 1) == (OK, p.ERR2_ALERT)
    assert ph.read1ByteTxRx(port, 2, 64)[0] == 0  # only a reboot re-enables torque
    assert ph.reboot(port, 2)[0] == OK
    v2_bus.settle()
    assert ph.read4ByteTxRx(port, 2, 112) == (0, OK, 0)
    assert ph.write1ByteTxRx(port, 2, 64, 1) == (OK, 0)
    assert ph.read1ByteTxRx(port, 2, 64) == (1, OK, 0)


def test_reverse_mode_turns_present_velocity_with_present_position() -> None:
    t = [0.0]
    servo = SimServo(1, "XM430-W350")
    bus = SimulatedBus([servo], protocol=2.0, clock=lambda: t[0])
    bus.feed(p.build_v2(1, p.INST_WRITE, le(10, 2) + b"\x01"))  # drive mode: reverse
    bus.feed(p.build_v2(1, p.INST_WRITE, le(64, 2) + b"\x01"))
    start = servo.get("present_position")
    bus.feed(p.build_v2(1, p.INST_WRITE, le(116, 2) + le(start + 400, 4)))
    t[0] += 0.02
    bus.feed(p.build_v2(1, p.INST_PING, b""))
    assert servo.get("present_position") > start
    assert servo.get("present_velocity") > 0


def test_factory_reset_clear_and_action_as_the_e_manual_says(
    v2_client: Client, v1_client: Client, v2_bus: SimulatedBus
) -> None:
    port, ph = v2_client
    assert ph.write1ByteTxRx(port, 1, 9, 0) == (OK, 0)  # return delay 0
    assert ph.factoryReset(port, 1, 0x02) == (OK, 0)  # all but ID and baud rate
    v2_bus.settle()
    assert ph.read1ByteTxRx(port, 1, 9) == (250, OK, 0)
    assert ph.read1ByteTxRx(port, 1, 8) == (4, OK, 0)
    assert ph.factoryReset(port, 5, 0x01) == (OK, 0)  # baud rate too: 57600 now
    v2_bus.settle()
    assert ph.ping(port, 5)[1] == TIMEOUT
    assert ph.clearMultiTurn(port, 2) == (OK, 0)
    (reply,) = _replies_v2(v2_bus.feed(p.build_v2(2, p.INST_ACTION, b"")))
    assert reply.code == p.ERR2_INSTRUCTION  # Action with nothing registered
    port1, ph1 = v1_client
    assert ph1.regWriteTxRx(port1, 36, 30, 2, [0x58, 0x02]) == (OK, 0)
    assert ph1.action(port1, 36) == OK  # a unicast Action is answered on Protocol 1.0
    assert ph1.read2ByteTxRx(port1, 36, 30) == (600, OK, 0)
    assert ph1.write1ByteTxRx(port1, 11, 5, 7) == (OK, 0)
    assert ph1.factoryReset(port1, 11) == (OK, 0)  # everything: ID 1, 57142 bps (34)
    assert ph1.ping(port1, 1)[1] == TIMEOUT  # not at 1 Mbps any more
    assert port1.setBaudRate(57600)  # within 3 % of the servo's rate
    assert ph1.ping(port1, 1)[1:] == (OK, 0)
    assert ph1.read1ByteTxRx(port1, 1, 5)[0] == 250


def test_a_status_packet_on_the_line_is_not_executed(v2_bus: SimulatedBus) -> None:
    status = p.build_status_v2(1, 0x01)
    assert v2_bus.feed(status) == b""


def _write_v2(bus: SimulatedBus, address: int, value: int, size: int, sid: int = 1) -> int:
    packet = p.build_v2(sid, p.INST_WRITE, le(address, 2) + le(value, size))
    (reply,) = _replies_v2(bus.feed(packet))
    return reply.code


def test_operating_modes_and_register_ranges_of_an_xm430() -> None:
    """Modes 4 and 5 take goals over ±256 turns (LeRobot's arms and grippers use them);
    velocity mode turns at Goal Velocity, within Velocity Limit; values a register does not
    take are a Data Range Error, goals past their limit register a Data Limit Error."""
    t = [0.0]
    servo = SimServo(1, "XM430-W350")
    bus = SimulatedBus([servo], protocol=2.0, clock=lambda: t[0])
    assert _write_v2(bus, 11, 5, 1) == 0  # current-based position
    assert _write_v2(bus, 116, 10_000, 4) == 0
    assert _write_v2(bus, 116, -5_000, 4) == 0
    assert _write_v2(bus, 11, 1, 1) == 0  # velocity
    assert _write_v2(bus, 104, 5_000, 4) == 0x06  # over Velocity Limit (200)
    assert _write_v2(bus, 104, 100, 4) == 0
    assert _write_v2(bus, 64, 1, 1) == 0
    start = servo.get("present_position")
    t[0] += 1.0
    bus.feed(p.build_v2(1, p.INST_PING, b""))
    turned = servo.get("present_position") - start  # 100 × 0.229 rpm for 1 s ≈ 156 ticks
    assert turned == pytest.approx(100 * 0.229 / 60 * 4096, rel=0.02)
    assert servo.get("present_velocity") == 100
    assert _write_v2(bus, 64, 0, 1) == 0
    for address, value, size in ((11, 2, 1), (8, 200, 1), (64, 7, 1), (68, 5, 1), (7, 253, 1)):
        assert _write_v2(bus, address, value, size) == 0x04, address
    assert _write_v2(bus, 102, 5_000, 2) == 0x06  # Goal Current over Current Limit
    assert _write_v2(bus, 100, 1_000, 2) == 0x06  # Goal PWM over PWM Limit


def test_wheel_and_multi_turn_modes_of_protocol_1_servos(v1_bus: SimulatedBus) -> None:
    """AX/MX with both angle limits 0: a wheel, turning at Moving Speed (bit 10: clockwise),
    Goal Position unused; MX with both at 4095: multi-turn, goals over ±28672."""

    def write(sid: int, address: int, value: int, size: int) -> int:
        out = v1_bus.feed(p.build_v1(sid, p.INST_WRITE, bytes((address,)) + le(value, size)))
        return p.parse_v1(out, status=True).code

    assert write(11, 6, 4095 | 4095 << 16, 4) == 0  # CW = CCW = 4095
    assert write(11, 30, 6_000, 2) == 0
    assert write(11, 30, -5_000, 2) == 0
    assert write(11, 30, 30_000, 2) == p.ERR1_ANGLE_LIMIT
    assert write(36, 6, 0, 4) == 0  # wheel
    assert write(36, 30, 512, 2) == 0  # not used
    assert write(36, 32, 1024 | 500, 2) == 0  # clockwise, 500 units
    assert write(36, 24, 1, 1) == 0
    wheel = v1_bus.servos[36]
    wheel.advance(0.1)
    assert wheel.dynamics.velocity_rad_s == pytest.approx(-500 * wheel.table.velocity_unit_rad_s)
    assert wheel.get("present_speed") == 1024 | 500


def test_indirect_addresses_of_an_xm430(v2_client: Client, v2_bus: SimulatedBus) -> None:
    """As ROBOTIS-Framework (OP3's own controller) uses them: Indirect Address k names a
    register byte, Indirect Data k reads and writes it under that register's rules; factory
    addresses name the data bytes themselves."""
    port, ph = v2_client
    assert ph.write1ByteTxRx(port, 1, 224, 7) == (OK, 0)  # factory: its own storage
    assert ph.read1ByteTxRx(port, 1, 224) == (7, OK, 0)
    for k in range(4):  # Indirect Data 1–4 → Present Position, 5–8 → Goal Position
        assert ph.write2ByteTxRx(port, 1, 168 + 2 * k, 132 + k) == (OK, 0)
        assert ph.write2ByteTxRx(port, 1, 176 + 2 * k, 116 + k) == (OK, 0)
    present = v2_bus.servos[1].get("present_position")
    assert ph.read4ByteTxRx(port, 1, 224) == (present, OK, 0)
    assert ph.write4ByteTxRx(port, 1, 228, 1000) == (OK, 0)
    assert ph.read4ByteTxRx(port, 1, 116) == (1000, OK, 0)
    assert ph.write4ByteTxRx(port, 1, 228, 5000) == (OK, 0x06)  # past Max Position Limit
    assert ph.write4ByteTxRx(port, 1, 224, 0) == (OK, 0x07)  # Present Position is read-only
    assert ph.write2ByteTxRx(port, 1, 168, 700) == (OK, 0x04)  # names no register byte
    assert ph.write2ByteTxRx(port, 1, 168, 9) == (OK, 0x04)  # EEPROM: only 64–661 named
    assert ph.write2ByteTxRx(port, 1, 168, 64) == (OK, 0)  # Torque Enable
    assert ph.write1ByteTxRx(port, 1, 224, 7) == (OK, 0x04)  # Torque Enable takes 0 or 1
    assert ph.write1ByteTxRx(port, 1, 224, 1) == (OK, 0)
    assert v2_bus.servos[1].torque_on


def test_twins_both_move_and_a_reboot_forgets_a_reg_write() -> None:
    t = [0.0]
    a, b = SimServo(1, "XM430-W350"), SimServo(2, "XM430-W350")
    bus = SimulatedBus([a, b], protocol=2.0, clock=lambda: t[0])
    bus.feed(p.build_v2(2, p.INST_WRITE, le(7, 2) + b"\x01"))  # 2 → 1: twins
    bus.feed(p.build_v2(1, p.INST_WRITE, le(64, 2) + b"\x01"))
    bus.feed(p.build_v2(1, p.INST_WRITE, le(116, 2) + le(3000, 4)))
    t[0] += 1.0
    bus.feed(p.build_v2(1, p.INST_PING, b""))
    assert a.get("present_position") > 2900
    assert b.get("present_position") > 2900
    bus.feed(p.build_v2(1, p.INST_REG_WRITE, le(65, 2) + b"\x01"))
    a.reboot()
    assert a.registered is None
