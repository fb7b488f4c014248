"""A simulated Dynamixel bus served byte for byte on a pseudo-terminal.

The real dynamixel-sdk + pyserial open the pty's slave path like a USB adapter; this object
reads the master side, frames and checks every packet strictly (header, length, CRC-16 or
checksum, Protocol 2.0 byte stuffing), runs the instruction on its
:class:`robot_retarget.sim.servo.SimServo` objects and writes the status packets back.
Optional wire-time model: replies come no earlier than the bytes would take on a real bus at
the configured baud rate (10 bits per byte), plus each servo's return delay. Fault injection:
dropped, corrupt, late or noisy replies, hardware error bits, an unplugged port.

An unstuffed ``FF FF FD`` in a Protocol 2.0 payload (what dynamixel-sdk 4.1.0 sends: its
``txPacket`` drops the stuffed copy) gets **no reply**. Decided from the protocol definition:
the sender must insert ``FD`` after every ``FF FF FD`` in INST + PARAMS and LEN counts the
stuffed bytes; a receiver removes the ``FD`` after each ``FF FF FD``. Without it the bytes
after ``FF FF FD`` are neither a stuffing byte nor payload the length field accounts for —
to the servo it is a header inside a packet, so the frame it was in is malformed, not a
packet with a bad CRC: the servo never framed a packet it could answer (not even with a CRC
error status) and waits for the next header. The client times out; nothing is written.

What the servos hear and answer, as on a real bus:

- **Baud rate.** Each servo is set to the bus's rate (its Baud Rate register) and hears only a
  client within 3 % of its own rate, read from the pty's terminal settings
  (:mod:`robot_retarget.sim.line_speed`); a write to Baud Rate moves it to the new rate after
  its reply. A client that never set a speed is heard by all.
- **ID.** A servo answers to its ID register: a write there moves it. Two servos on one ID both
  act on what is sent to it and answer at once, so their replies collide (a corrupt packet).
- **Status Return Level.** 0: a status for PING only; 1: for PING and reads; 2: for all.
- **Status packets** on the line (instruction 0x55, another servo's reply) are not executed.
- A packet whose answer could not be built (a reply longer than a packet can carry) gets no
  reply and is logged; nothing a client sends stops the simulator.

Runs in a background thread (tests) or standalone::

    python -m robot_retarget.sim.dxl_bus --robot op3          # first line: PORT /dev/pts/N
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import os
import select
import signal
import sys
import threading
import time
import tty
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from types import FrameType, TracebackType

from robot_retarget.hardware import protocol as p
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.servo_models import (
    baud_register_value,
    baud_supported,
    bauds_match,
    register_baud,
)
from robot_retarget.sim.line_speed import client_baud
from robot_retarget.sim.servo import OK, RESULT_FAIL, SimServo

_INCOMPLETE_PACKET_TIMEOUT_S = 0.05
# Stray bytes with a false Protocol 1.0 and 2.0 header in them, as a noisy line might deliver.
_LINE_NOISE = bytes((0x00, 0xFF, 0x13, 0xFF, 0xFF, 0xFD, 0x00, 0x7F, 0xFF, 0xFF, 0x07))
USB2AX_SYNC_READ = 0x84  # USB2AX's own instruction (Protocol 1.0 has no Sync Read)
USB2AX_ID = 0xFD
_FACTORY_RESET = 0x06
_CLEAR = 0x10
_MAX_V1_PARAMS = 0xFF - 2  # LEN = params + 2 must fit one byte
# Instructions a servo at Status Return Level 1 still answers (reads); at 0 only PING.
_READS = frozenset(
    (p.INST_READ, p.INST_SYNC_READ, p.INST_BULK_READ, p.INST_FAST_SYNC_READ,
     p.INST_FAST_BULK_READ, USB2AX_SYNC_READ)
)  # fmt: skip
_WRITES = frozenset(
    (p.INST_WRITE, p.INST_ACTION, p.INST_SYNC_WRITE, p.INST_BULK_WRITE, _FACTORY_RESET)
)  # fmt: skip


@dataclass
class Faults:
    """What to break next. Counters count down as replies are affected."""

    drop_replies: int = 0
    corrupt_replies: int = 0
    late_replies: int = 0
    late_reply_s: float = 0.05
    noise_replies: int = 0  # line noise: stray bytes (a false header among them) before a reply
    only_id: int | None = None  # restrict reply faults to this servo (None: any)

    def _applies(self, servo_id: int) -> bool:
        return self.only_id is None or self.only_id == servo_id


@dataclass
class BusLog:
    """Everything the bus received: raw accepted packets and rejected ones with the reason."""

    packets: collections.deque[bytes] = field(
        default_factory=lambda: collections.deque(maxlen=200_000)
    )
    rejected: list[tuple[bytes, str]] = field(default_factory=list)


class SimulatedBus:
    """Servos on one simulated serial bus. Use as a context manager or start()/stop()."""

    def __init__(
        self,
        servos: Iterable[SimServo],
        *,
        protocol: float,
        baud_rate: int = 1_000_000,
        wire_time: bool = False,
        clock: Callable[[], float] = time.monotonic,
        usb2ax: bool = False,
    ) -> None:
        if protocol not in (1.0, 2.0):
            raise ValueError(f"protocol must be 1.0 or 2.0, got {protocol!r}")
        self.protocol = float(protocol)
        members = list(servos)
        for s in members:
            if s.protocol != self.protocol:
                raise ValueError(
                    f"servo {s.servo_id} ({s.table.model}) speaks Protocol {s.protocol}, "
                    f"the bus Protocol {self.protocol}"
                )
            if baud_supported(self.protocol, baud_rate):  # the servos were set to the bus's rate
                s._put("baud_rate", baud_register_value(self.protocol, baud_rate))
        # The bus's servos by the ID they answer to (tests add and remove servos here); a servo
        # moved onto an ID another one holds waits in _twins (see _rekey).
        self.servos: dict[int, SimServo] = {}
        self._twins: list[SimServo] = members
        self._on_id: dict[int, list[SimServo]] = {}
        self._rekey()
        self._heard = self._on_id  # the servos that hear the packet being executed
        self._as_id: int | None = None  # the ID a unicast packet addressed
        self.baud_rate = baud_rate
        self.wire_time = wire_time
        # Protocol 1.0 through a USB2AX adapter, as Poppy's own software expects: the adapter
        # answers SYNC_READ (0x84) itself, with every listed servo's data in one packet.
        self.usb2ax = usb2ax and self.protocol == 1.0
        self._clock = clock
        self.faults = Faults()
        self.log = BusLog()
        self._lock = threading.RLock()
        self._master: int | None = None
        self._slave: int | None = None
        self.port: str | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._buf = bytearray()
        self._last_rx = 0.0
        self._last_advance = clock()
        self._bus_free_at = 0.0
        self.unplugged = False
        self._busy = False  # between reading bytes and having answered them

    # ----- lifecycle -------------------------------------------------------------------------
    def start(self) -> str:
        """Open the pty and serve it from a daemon thread; returns the port path."""
        self.open()
        self._thread = threading.Thread(target=self.serve, name="sim-dxl-bus", daemon=True)
        self._thread.start()
        return self.port or ""

    def open(self) -> str:
        master, slave = os.openpty()
        tty.setraw(slave)
        # The slave stays open here too: otherwise closing the last client end makes the
        # master read EIO and the bus could not be reopened by the next client.
        self._master, self._slave = master, slave
        self.port = os.ttyname(slave)
        self._opened_baud = client_baud(slave)  # the pty's own; a client changes it
        return self.port

    def _client_baud(self) -> int | None:
        """The rate the client set on the port (None: none set, or unreadable)."""
        if self._slave is None:
            return None
        baud = client_baud(self._slave)
        return None if baud == self._opened_baud else baud

    def _rekey(self) -> None:
        """Map IDs to servos from their ID registers (before each packet, and after a write:
        an ID may have moved)."""
        listed = list(self.servos.values())
        known = {id(m) for m in listed}
        members = listed + [t for t in self._twins if id(t) not in known]
        on_id: dict[int, list[SimServo]] = {}
        for s in members:
            on_id.setdefault(s.servo_id, []).append(s)
        self._on_id = on_id
        self.servos = {i: group[0] for i, group in sorted(on_id.items())}
        self._twins = [s for group in on_id.values() for s in group[1:]]

    def _hearing(self) -> dict[int, list[SimServo]]:
        """The servos that understand the client: at its baud rate (all if it set none)."""
        self._rekey()
        baud = self._client_baud()
        if baud is None:
            return self._on_id
        heard: dict[int, list[SimServo]] = {}
        for i, group in self._on_id.items():
            ok = [s for s in group if _hears(s, baud)]
            if ok:
                heard[i] = ok
        return heard

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        self._close_fds()

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = None

    def unplug(self) -> None:
        """Simulate pulling the USB cable: the device goes away, clients get I/O errors."""
        self.unplugged = True
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
            self._thread = None
        self._close_fds()

    def __enter__(self) -> SimulatedBus:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    # ----- serving ---------------------------------------------------------------------------
    def serve(self) -> None:
        """Serve until stop(); reads the master side and answers packets."""
        master = self._master
        if master is None:
            raise RuntimeError("SimulatedBus.serve() before open()")
        while not self._stop.is_set():
            ready, _, _ = select.select([master], [], [], 0.05)
            if not ready:
                self._drop_stale_partial()
                continue
            self._busy = True
            try:
                chunk = os.read(master, 65536)
            except OSError:
                chunk = b""  # no client has the port open right now
            if chunk:
                now = self._clock()
                self._last_rx = now
                self._buf.extend(chunk)
                self._process_buffer(now)
            self._busy = False

    def settle(self, quiet_s: float = 0.01, timeout_s: float = 2.0) -> None:
        """Wait until every byte sent to the bus so far has been processed: nothing pending on
        the pty, no packet half-processed, and no new packet for ``quiet_s``."""
        deadline = time.monotonic() + timeout_s
        count = -1
        while time.monotonic() < deadline:
            now_count = len(self.log.packets) + len(self.log.rejected)
            master = self._master
            pending = False
            if master is not None:
                try:
                    pending = bool(select.select([master], [], [], 0.0)[0])
                except (OSError, ValueError):
                    pending = False
            if now_count == count and not pending and not self._busy and not self._buf:
                return
            count = now_count
            time.sleep(quiet_s)

    def feed(self, data: bytes) -> bytes:
        """Process bytes as if received on the wire; returns the reply bytes (for unit tests)."""
        out = bytearray()
        self._buf.extend(data)
        self._process_buffer(self._clock(), out)
        return bytes(out)

    def _drop_stale_partial(self) -> None:
        if self._buf and self._clock() - self._last_rx > _INCOMPLETE_PACKET_TIMEOUT_S:
            self.log.rejected.append((bytes(self._buf), "incomplete packet timed out"))
            self._buf.clear()

    def _process_buffer(self, now: float, sink: bytearray | None = None) -> None:
        buf = self._buf
        v2 = self.protocol == 2.0
        while buf:
            start = p.find_header(buf, self.protocol)
            if start:
                del buf[:start]
                if not buf:
                    return
            total = p.packet_length_v2(buf) if v2 else p.packet_length_v1(buf)
            if total is None or len(buf) < total:
                return
            raw = bytes(buf[:total])
            del buf[:total]
            try:
                packet = p.parse_v2(raw) if v2 else p.parse_v1(raw, status=False)
            except p.MalformedPacketError as exc:
                self.log.rejected.append((raw, str(exc)))
                self._reply_checksum_error(raw, now, sink)
                continue
            self.log.packets.append(raw)
            with self._lock:
                try:
                    replies = self._execute(packet, now)
                except Exception as exc:  # a client's packet must never stop the bus
                    self.log.rejected.append((raw, f"no reply could be built: {exc}"))
                    continue
            self._send(replies, len(raw), now, sink)

    def _reply_checksum_error(self, raw: bytes, now: float, sink: bytearray | None) -> None:
        # A servo that can read its own ID reports a CRC/checksum error; malformed stuffing
        # (a false header inside the payload) gets no reply, as the firmware would resync.
        if b"\xff\xff\xfd" in raw[7:-2] and self.protocol == 2.0:
            return
        sid = raw[4] if self.protocol == 2.0 else raw[2]
        heard = self._hearing().get(sid)
        if not heard:
            return
        servo = heard[0]
        if self.protocol == 2.0:
            reply = p.build_status_v2(sid, p.ERR2_CRC | (0x80 if servo.hardware_error else 0))
        else:
            reply = p.build_status_v1(sid, p.ERR1_CHECKSUM | (servo.hardware_error & 0x25))
        self._send([(sid, reply)], len(raw), now, sink)

    def _send(
        self,
        replies: Sequence[tuple[int, bytes]],
        n_in: int,
        t_rx: float,
        sink: bytearray | None,
    ) -> None:
        out = bytearray()
        late_s = 0.0
        for sid, reply in replies:
            f = self.faults
            if f.drop_replies > 0 and f._applies(sid):
                f.drop_replies -= 1
                continue
            if f.corrupt_replies > 0 and f._applies(sid):
                f.corrupt_replies -= 1
                reply = reply[:-1] + bytes(((reply[-1] ^ 0x5A),))
            if f.noise_replies > 0 and f._applies(sid):
                f.noise_replies -= 1
                reply = _LINE_NOISE + reply
            if f.late_replies > 0 and f._applies(sid):
                f.late_replies -= 1
                late_s = max(late_s, f.late_reply_s)
            out += reply
        if self.wire_time:
            byte_s = 10.0 / self.baud_rate
            start = max(t_rx, self._bus_free_at)
            delay_s = sum(
                2e-6 * self.servos[sid].get("return_delay_time")
                for sid, _ in replies
                if sid in self.servos
            )  # fmt: skip
            done = start + (n_in + len(out)) * byte_s + delay_s
            self._bus_free_at = done
            _sleep_until(done, self._clock)
        if late_s:
            time.sleep(late_s)
        if not out:
            return
        if sink is not None:
            sink += out
        elif self._master is not None:
            with contextlib.suppress(OSError):
                os.write(self._master, out)

    # ----- instructions ----------------------------------------------------------------------
    def _advance(self, now: float) -> None:
        dt = now - self._last_advance
        if dt > 0.0:
            for group in self._on_id.values():  # twins on one ID move too
                for servo in group:
                    servo.advance(dt)
            self._last_advance = now

    def _execute(self, pkt: p.Packet, now: float) -> list[tuple[int, bytes]]:
        self._advance(now)
        if pkt.is_status:
            return []  # another servo's reply on the line (Protocol 2.0): nothing to do
        self._heard = self._hearing()
        self._as_id = None if pkt.servo_id == p.BROADCAST_ID else pkt.servo_id
        levels = {i: g[0].status_return_level for i, g in self._heard.items()}
        try:
            replies = self._execute_v2(pkt) if self.protocol == 2.0 else self._execute_v1(pkt)
        finally:
            self._heard, self._as_id = self._on_id, None
            if pkt.code in _WRITES:
                self._rekey()
        if pkt.code != p.INST_PING:
            level = 1 if pkt.code in _READS else 2
            replies = [(i, r) for i, r in replies if levels.get(i, 2) >= level]
        return _collided(replies)

    def _targets(self, sid: int) -> list[SimServo]:
        if sid == p.BROADCAST_ID:
            return [s for i in sorted(self._heard) for s in self._heard[i]]
        return list(self._heard.get(sid, ()))

    def _listed(self, sid: int) -> list[SimServo]:
        """The servos on ``sid`` that hear the packet (a Sync / Bulk instruction's list)."""
        return list(self._heard.get(sid, ())) if sid != p.BROADCAST_ID else []

    def _status(self, servo: SimServo, code: int, params: bytes = b"") -> tuple[int, bytes]:
        # A unicast reply comes from the ID addressed, even where the write moved the servo.
        sid = servo.servo_id if self._as_id is None else self._as_id
        if self.protocol == 2.0:
            return sid, p.build_status_v2(sid, servo.status_error_v2(code), params)
        return sid, p.build_status_v1(sid, servo.status_error_v1(code), params)

    def _instruction_error(self, servo: SimServo) -> tuple[int, bytes]:
        if self.protocol == 2.0:
            err = p.ERR2_INSTRUCTION | (0x80 if servo.hardware_error else 0)
            return servo.servo_id, p.build_status_v2(servo.servo_id, err)
        err = p.ERR1_INSTRUCTION | (servo.hardware_error & 0x25)
        return servo.servo_id, p.build_status_v1(servo.servo_id, err)

    def _execute_v2(self, pkt: p.Packet) -> list[tuple[int, bytes]]:
        inst, prm, sid = pkt.code, pkt.params, pkt.servo_id
        bcast = sid == p.BROADCAST_ID
        replies: list[tuple[int, bytes]] = []
        if inst == p.INST_PING:
            for s in self._targets(sid):
                info = p.le_bytes(s.get("model_number"), 2) + bytes((s.get("firmware_version"),))
                replies.append(self._status(s, OK, info))
            return replies
        if inst in (p.INST_READ, p.INST_WRITE, p.INST_REG_WRITE) and len(prm) < 3 + (
            inst == p.INST_READ
        ):
            return [self._status(s, 3) for s in self._targets(sid) if not bcast]
        if inst == p.INST_READ:
            addr, length = prm[0] | prm[1] << 8, prm[2] | prm[3] << 8
            for s in self._targets(sid) if not bcast else []:
                code, data = s.read(addr, length)
                replies.append(self._status(s, code, data))
            return replies
        if inst == p.INST_WRITE:
            addr = prm[0] | prm[1] << 8
            for s in self._targets(sid):
                code = s.write(addr, prm[2:])
                if not bcast:
                    replies.append(self._status(s, code))
            return replies
        if inst == p.INST_REG_WRITE:
            for s in self._targets(sid):
                s.registered = (prm[0] | prm[1] << 8, bytes(prm[2:]))
                s._put("registered_instruction", 1)
                if not bcast:
                    replies.append(self._status(s, OK))
            return replies
        if inst == p.INST_ACTION:
            for s in self._targets(sid):
                if s.registered is None:  # e-Manual: Action without a Reg Write
                    if not bcast:
                        replies.append(self._instruction_error(s))
                    continue
                s.write(*s.registered)
                s.registered = None
                s._put("registered_instruction", 0)
                if not bcast:
                    replies.append(self._status(s, OK))
            return replies
        if inst == _FACTORY_RESET and prm[:1] in (b"\xff", b"\x01", b"\x02"):
            # 0xFF: everything; 0x01: all but the ID; 0x02: all but the ID and baud rate.
            # Broadcast resets only with 0x01 / 0x02 (e-Manual: 0xFF is refused there).
            if bcast and prm[0] == 0xFF:
                return replies
            for s in self._targets(sid):
                if not bcast:
                    replies.append(self._status(s, OK))
                s.factory_reset(keep_id=prm[0] != 0xFF, keep_baud=prm[0] == 0x02)
            return replies
        if inst == _CLEAR and prm[:1] == b"\x01":
            # Clear multi-turn revolutions: present position back within one turn; torque off
            # only (e-Manual: refused with torque on, or while moving).
            for s in self._targets(sid):
                code = OK if not s.torque_on else RESULT_FAIL
                if code == OK:
                    s.clear_turns()
                if not bcast:
                    replies.append(self._status(s, code))
            return replies
        if inst == p.INST_REBOOT:
            for s in self._targets(sid):
                if not bcast:
                    replies.append(self._status(s, OK))
                s.reboot()
            return replies
        if inst in (p.INST_SYNC_READ, p.INST_FAST_SYNC_READ) and bcast and len(prm) >= 4:
            addr, length = prm[0] | prm[1] << 8, prm[2] | prm[3] << 8
            listed = [s for i in prm[4:] for s in self._listed(i)]
            if inst == p.INST_SYNC_READ:
                for s in listed:
                    code, data = s.read(addr, length)
                    replies.append(self._status(s, code, data))
                return replies
            return self._fast_read([(s, addr, length) for s in listed])
        if inst == p.INST_FAST_BULK_READ and bcast:
            items = [
                (s, prm[k + 1] | prm[k + 2] << 8, prm[k + 3] | prm[k + 4] << 8)
                for k in range(0, len(prm) - 4, 5)
                for s in self._listed(prm[k])
            ]
            return self._fast_read(items)
        if inst == p.INST_SYNC_WRITE and bcast and len(prm) >= 4:
            addr, length = prm[0] | prm[1] << 8, prm[2] | prm[3] << 8
            body = prm[4:]
            for k in range(0, len(body) - length, length + 1):
                for servo in self._listed(body[k]):
                    servo.write(addr, body[k + 1 : k + 1 + length])
            return replies
        if inst == p.INST_BULK_READ and bcast:
            for k in range(0, len(prm) - 4, 5):
                listed = self._listed(prm[k])
                if not listed:
                    break  # each reply waits for the one before it: the chain ends here
                for servo in listed:
                    code, data = servo.read(
                        prm[k + 1] | prm[k + 2] << 8, prm[k + 3] | prm[k + 4] << 8
                    )
                    replies.append(self._status(servo, code, data))
            return replies
        if inst == p.INST_BULK_WRITE and bcast:
            k = 0
            while k + 5 <= len(prm):
                addr, length = prm[k + 1] | prm[k + 2] << 8, prm[k + 3] | prm[k + 4] << 8
                for servo in self._listed(prm[k]):
                    servo.write(addr, prm[k + 5 : k + 5 + length])
                k += 5 + length
            return replies
        return [self._instruction_error(s) for s in self._targets(sid) if not bcast]

    def _fast_read(self, items: list[tuple[SimServo, int, int]]) -> list[tuple[int, bytes]]:
        """Fast Sync / Fast Bulk Read: one status packet from ID 0xFE with [ERR ID DATA CRC] per
        servo; each servo's CRC is the running CRC of the packet so far, the last one the
        packet's own CRC. Each servo appends its part after the one before it, so the chain
        ends at the first servo whose firmware predates the instruction (e-Manual: v45 on the
        XM430): nothing if it is the first, else a packet cut short (the client times out)."""
        if not items:
            return []
        total = 1 + sum(length + 4 for _, _, length in items)  # the length field's value
        if total > 0xFFFF:
            raise ValueError(f"a Fast Read reply of {total} bytes does not fit one packet")
        pkt = bytearray(p.HEADER_V2 + bytes((p.BROADCAST_ID, total & 0xFF, total >> 8, 0x55)))
        crc = p.crc16(pkt)  # carried along: each part's CRC covers everything before it
        for k, (s, addr, length) in enumerate(items):
            if s.get("firmware_version") < s.table.fast_sync_read_min_firmware:
                return [(items[0][0].servo_id, bytes(pkt))] if k else []
            code, data = s.read(addr, length)
            part = bytes((s.status_error_v2(code), s.servo_id)) + data.ljust(length, b"\0")
            crc = p.crc16(part, crc)
            crc_bytes = bytes((crc & 0xFF, crc >> 8))
            pkt += part + crc_bytes
            crc = p.crc16(crc_bytes, crc)
        return [(items[0][0].servo_id, bytes(pkt))]

    def _execute_v1(self, pkt: p.Packet) -> list[tuple[int, bytes]]:
        inst, prm, sid = pkt.code, pkt.params, pkt.servo_id
        bcast = sid == p.BROADCAST_ID
        replies: list[tuple[int, bytes]] = []
        if inst == p.INST_PING:
            return [self._status(s, OK) for s in self._targets(sid) if not bcast]
        if inst == p.INST_READ and len(prm) == 2:
            for s in self._targets(sid) if not bcast else []:
                code, data = s.read(prm[0], prm[1])
                replies.append(self._status(s, code, data))
            return replies
        if inst in (p.INST_WRITE, p.INST_REG_WRITE) and len(prm) >= 2:
            for s in self._targets(sid):
                if inst == p.INST_WRITE:
                    code = s.write(prm[0], prm[1:])
                else:
                    s.registered, code = (prm[0], bytes(prm[1:])), OK
                    s._put("registered", 1)
                if not bcast:
                    replies.append(self._status(s, code))
            return replies
        if inst == p.INST_ACTION:
            for s in self._targets(sid):
                if s.registered is not None:
                    s.write(*s.registered)
                    s.registered = None
                    s._put("registered", 0)
                if not bcast:  # a unicast Action is answered (Protocol 1.0 e-Manual)
                    replies.append(self._status(s, OK))
            return replies
        if inst == _FACTORY_RESET and not prm:
            for s in self._targets(sid):  # Protocol 1.0: everything, the ID to 1 too
                if not bcast:
                    replies.append(self._status(s, OK))
                s.factory_reset(keep_id=False, keep_baud=False)
            return replies
        if inst == p.INST_SYNC_WRITE and bcast and len(prm) >= 2:
            addr, length = prm[0], prm[1]
            body = prm[2:]
            for k in range(0, len(body) - length, length + 1):
                for servo in self._listed(body[k]):
                    servo.write(addr, body[k + 1 : k + 1 + length])
            return replies
        if inst == USB2AX_SYNC_READ and bcast and self.usb2ax and len(prm) >= 3:
            return self._usb2ax_sync_read(prm[0], prm[1], list(prm[2:]))
        if inst == p.INST_BULK_READ and bcast and len(prm) >= 1:
            for k in range(1, len(prm) - 2, 3):
                length, bid, addr = prm[k], prm[k + 1], prm[k + 2]
                listed = self._listed(bid)
                if not listed or not all(s.table.bulk_read for s in listed):
                    # Each module answers after the one listed before it (MX e-Manual, Bulk
                    # Read): a missing servo or an AX (no Bulk Read) ends the reply chain.
                    break
                for servo in listed:
                    code, data = servo.read(addr, length)
                    replies.append(self._status(servo, code, data))
            return replies
        return [self._instruction_error(s) for s in self._targets(sid) if not bcast]

    def _usb2ax_sync_read(self, addr: int, length: int, ids: list[int]) -> list[tuple[int, bytes]]:
        """The adapter reads each listed servo and answers once, from its own ID (0xFD), with
        the data concatenated in list order; a missing servo leaves it silent (a timeout)."""
        data = bytearray()
        for sid in ids:
            listed = self._listed(sid)
            if len(listed) != 1:
                return []  # missing, or two servos answering at once: the adapter times out
            code, chunk = listed[0].read(addr, length)
            if code != OK:
                return []
            data += chunk
        if len(data) > _MAX_V1_PARAMS:
            raise ValueError(f"{len(data)} bytes of data do not fit one Protocol 1.0 packet")
        return [(USB2AX_ID, p.build_status_v1(USB2AX_ID, 0, bytes(data)))]


def _hears(servo: SimServo, host_baud: int) -> bool:
    rate = register_baud(servo.protocol, servo.get("baud_rate"))
    return rate is not None and bauds_match(host_baud, rate)


def _collided(replies: list[tuple[int, bytes]]) -> list[tuple[int, bytes]]:
    """Replies of servos sharing an ID go out at once: one corrupt packet in their place."""
    seen: dict[int, int] = {}
    out: list[tuple[int, bytes]] = []
    for sid, reply in replies:
        if sid in seen:
            k = seen[sid]
            first = out[k][1]
            out[k] = (sid, first[:-1] + bytes((first[-1] ^ reply[-1] ^ 0xA5,)))
            continue
        seen[sid] = len(out)
        out.append((sid, reply))
    return out


def _sleep_until(deadline: float, clock: Callable[[], float]) -> None:
    # Sleep for the bulk, spin for the last 0.2 ms: sleep() overshoots by ~0.1 ms on Linux.
    remaining = deadline - clock()
    if remaining > 3e-4:
        time.sleep(remaining - 2e-4)
    while clock() < deadline:
        pass


# ----- robots ----------------------------------------------------------------------------------
def servos_for_bus(
    config: RobotConfig, bus_name: str, q_rad: Sequence[float] | None = None
) -> list[SimServo]:
    """Simulated servos of one bus of a robot, horns at joint angles ``q_rad`` (default: the
    config's init pose), using the config's direction and zero offset."""
    q = config.init_pose if q_rad is None else q_rad
    servos = []
    for i, joint in enumerate(config.joints):
        if joint.bus != bus_name:
            continue
        s = SimServo(joint.servo_id, joint.servo_model)
        s.set_present_rad(joint.direction * float(q[i]) + joint.zero_offset_rad)
        servos.append(s)
    return servos


def buses_for_robot(
    config: RobotConfig,
    *,
    wire_time: bool = False,
    q_rad: Sequence[float] | None = None,
    usb2ax: bool = True,
) -> dict[str, SimulatedBus]:
    """One (not yet started) simulated bus per bus of the robot config; Protocol 1.0 buses
    behave as behind a USB2AX adapter unless ``usb2ax`` is False."""
    return {
        b.name: SimulatedBus(
            servos_for_bus(config, b.name, q_rad),
            protocol=b.protocol,
            baud_rate=b.baud_rate,
            wire_time=wire_time,
            usb2ax=usb2ax,
        )
        for b in config.buses
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m robot_retarget.sim.dxl_bus",
        description="Serve a robot's Dynamixel servos on pseudo-terminals until interrupted.",
    )
    parser.add_argument("--robot", required=True, help="robot config name or YAML path")
    parser.add_argument(
        "--wire-time", action="store_true", help="delay replies by the bytes' time on the wire"
    )
    args = parser.parse_args(argv)
    from robot_retarget.errors import RetargetError
    from robot_retarget.robot.loader import load_robot_config

    try:
        config = load_robot_config(args.robot)
    except RetargetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    buses = buses_for_robot(config, wire_time=args.wire_time)
    for bus in buses.values():
        bus.open()
    # First line(s): one PORT line per bus, in the config's bus order.
    for name, bus in buses.items():
        suffix = f" {name}" if len(buses) > 1 else ""
        print(f"PORT {bus.port}{suffix}", flush=True)
    for name, bus in buses.items():
        print(
            f"# {config.name} bus {name}: Protocol {bus.protocol}, {bus.baud_rate} bps, "
            f"IDs {sorted(bus.servos)}; Ctrl-C to stop",
            flush=True,
        )

    stop = threading.Event()

    def _on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    threads = [threading.Thread(target=b.serve, daemon=True) for b in buses.values()]
    for t in threads:
        t.start()
    while not stop.is_set():
        stop.wait(0.2)
    for bus in buses.values():
        bus.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
