"""One Dynamixel serial bus: transactions with bounded retries over the SDK's PortHandler.

Instruction packets are built with :mod:`robot_retarget.hardware.protocol` (correctly stuffed)
and written through the SDK's ``PortHandler`` (pyserial); status packets are framed and checked
here, waiting on the file descriptor instead of busy-polling like the SDK's ``rxPacket``.
Every failure of a transaction (timeout, bad CRC/checksum, wrong ID) is retried up to
``retries`` times and then raised as :class:`CommunicationError`; an unusable port (unplugged,
no permission) raises at once. Servo error bytes are returned, not judged: the backend decides
what a hardware error means.
"""

from __future__ import annotations

import contextlib
import select
import termios
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt
import serial

from robot_retarget.errors import CommunicationError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.sdk import TimedPortHandler, packet_handler
from robot_retarget.robot.config import RobotConfig

T = TypeVar("T")

# What pyserial lets through when the device vanishes (termios.error is not an OSError).
_PORT_ERRORS = (serial.SerialException, OSError, termios.error, ValueError)

# (servo error byte, data) per servo
ReadResult = dict[int, tuple[int, bytes]]
ByteArray = npt.NDArray[np.uint8]


class PortUnavailableError(CommunicationError):
    """The serial port cannot be used at all (missing, unplugged, no permission): not retried."""

    def __init__(self, message: str, *, port: str) -> None:
        self.port = port
        super().__init__(message)


@dataclass
class BusStats:
    transactions: int = 0
    retries: int = 0
    failures: int = 0


class DynamixelBus:
    """A bus on ``port_name`` speaking ``protocol`` at ``baud_rate``; open() before use.

    ``packet_timeout_ms`` is added to the wire time of the expected reply (the SDK's default is
    ≈ 34 ms); ``retries`` is how often a failed transaction is repeated.
    """

    def __init__(
        self,
        port_name: str,
        *,
        protocol: float,
        baud_rate: int,
        packet_timeout_ms: float = 4.0,
        retries: int = 2,
        name: str = "",
        port_hint: str = "",
    ) -> None:
        if float(protocol) not in (1.0, 2.0):
            raise ValueError(f"protocol must be 1.0 or 2.0, got {protocol!r}")
        if retries < 0:
            raise ValueError(f"retries must be ≥ 0, got {retries}")
        self.port_name = port_name
        self.protocol = float(protocol)
        self.baud_rate = baud_rate
        self.packet_timeout_ms = packet_timeout_ms
        self.retries = retries
        self.name = name or port_name
        # Where port_name came from, told if it cannot be opened (e.g. a config default the
        # user never typed, so they know which option names another).
        self.port_hint = port_hint
        self.stats = BusStats()
        self.port: Any = None
        self.handler: Any = packet_handler(self.protocol)
        self._v2 = self.protocol == 2.0

    # ----- port ------------------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self.port is not None and bool(self.port.is_open)

    def open(self) -> None:
        port = TimedPortHandler(self.port_name, self.packet_timeout_ms)
        try:
            ok = port.openPort() and port.setBaudRate(self.baud_rate)
        except _PORT_ERRORS as exc:
            hint = f"{self.port_hint}; " if self.port_hint else ""
            raise PortUnavailableError(
                f"cannot open serial port {self.port_name} ({exc}); {hint}check the cable, the "
                "port name (`robot-retarget doctor` lists ports) and that you are in the dialout "
                "group",
                port=self.port_name,
            ) from exc
        if not ok:
            raise PortUnavailableError(
                f"serial port {self.port_name} refused baud rate {self.baud_rate}",
                port=self.port_name,
            )
        self.port = port

    def close(self) -> None:
        if self.port is not None:
            # An unplugged adapter is already gone: nothing left to close.
            with contextlib.suppress(*_PORT_ERRORS):
                self.port.closePort()
            self.port = None

    def _require_port(self) -> Any:
        if self.port is None:
            raise PortUnavailableError(
                f"bus {self.name} is not open; call open() first", port=self.port_name
            )
        return self.port

    # ----- raw I/O ---------------------------------------------------------------------------
    def _unplugged(self, exc: BaseException) -> PortUnavailableError:
        return PortUnavailableError(
            f"serial port {self.port_name} failed ({exc}); the adapter was probably unplugged "
            "or powered off: reconnect it and start again",
            port=self.port_name,
        )

    def write_packet(self, packet: bytes) -> None:
        """Write a complete packet (input buffer cleared first, as the SDK does)."""
        port = self._require_port()
        try:
            port.clearPort()
            n = port.writePort(packet)
        except _PORT_ERRORS as exc:
            raise self._unplugged(exc) from exc
        if n != len(packet):
            raise CommunicationError(
                f"bus {self.name}: wrote {n} of {len(packet)} bytes; check the adapter"
            )

    def _read_exact(self, n_bytes: int, what: str) -> bytes:
        """Read ``n_bytes`` or raise CommunicationError when the packet timeout passes."""
        port = self._require_port()
        port.setPacketTimeout(n_bytes)
        deadline = time.monotonic() + port.packet_timeout / 1000.0
        buf = bytearray()
        fd = port.ser.fileno()
        try:
            while len(buf) < n_bytes:
                chunk = port.readPort(n_bytes - len(buf))
                if chunk:
                    buf += chunk
                    continue
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    break
                select.select([fd], [], [], remaining)
        except _PORT_ERRORS as exc:
            raise self._unplugged(exc) from exc
        if len(buf) < n_bytes:
            raise CommunicationError(
                f"bus {self.name}: {what}: timeout after {port.packet_timeout:.1f} ms with "
                f"{len(buf)} of {n_bytes} bytes (packet_timeout_ms={self.packet_timeout_ms}); "
                "check power, cabling, baud rate and IDs"
            )
        return bytes(buf)

    def _read_status(
        self, expect_ids: Sequence[int], sizes: Sequence[int], what: str
    ) -> ReadResult:
        """Read one status packet per ID (in order), each with ``sizes[i]`` data bytes."""
        overhead = 11 if self._v2 else 6
        total = sum(s + overhead for s in sizes)
        raw = self._read_exact(total, what)
        out: ReadResult = {}
        pos = 0
        for sid, size in zip(expect_ids, sizes, strict=True):
            length = p.packet_length_v2(raw[pos:]) if self._v2 else p.packet_length_v1(raw[pos:])
            if length is None:
                raise CommunicationError(f"bus {self.name}: {what}: truncated reply from {sid}")
            if pos + length > len(raw):
                # A stuffed reply is longer on the wire than its data: read the rest.
                raw += self._read_exact(pos + length - len(raw), what)
            pkt_bytes = raw[pos : pos + length]
            pos += length
            pkt = p.parse_v2(pkt_bytes) if self._v2 else p.parse_v1(pkt_bytes, status=True)
            if pkt.servo_id != sid or not pkt.is_status:
                raise CommunicationError(
                    f"bus {self.name}: {what}: expected a reply from ID {sid}, got ID "
                    f"{pkt.servo_id}"
                )
            if len(pkt.params) != size and not (pkt.code & 0x7F and not pkt.params):
                raise CommunicationError(
                    f"bus {self.name}: {what}: ID {sid} sent {len(pkt.params)} bytes, "
                    f"expected {size}"
                )
            out[sid] = (pkt.code, pkt.params)
        return out

    def transact(self, fn: Callable[[], T], what: str) -> T:
        """Run ``fn`` with bounded retries; PortUnavailableError is never retried."""
        self.stats.transactions += 1
        last: CommunicationError | None = None
        for attempt in range(self.retries + 1):
            if attempt:
                self.stats.retries += 1
            try:
                return fn()
            except PortUnavailableError:
                self.stats.failures += 1
                raise
            except CommunicationError as exc:
                last = exc
        self.stats.failures += 1
        raise CommunicationError(
            f"bus {self.name}: {what} failed {self.retries + 1} times; last error: {last}"
        ) from last

    # ----- instructions ----------------------------------------------------------------------
    def _packet(self, servo_id: int, instruction: int, params: bytes) -> bytes:
        if self._v2:
            return p.build_v2(servo_id, instruction, params)
        return p.build_v1(servo_id, instruction, params)

    def _addr(self, address: int) -> bytes:
        return p.le_bytes(address, 2) if self._v2 else bytes((address,))

    def ping(self, servo_id: int) -> int:
        """Model number of ``servo_id``."""
        return self.ping_info(servo_id)[0]

    def ping_info(self, servo_id: int) -> tuple[int, int]:
        """(model number, firmware version) of ``servo_id``. A Protocol 1.0 ping carries no
        data: both are read from the control table (addresses 0–2)."""
        if not self._v2:
            data = self.read(servo_id, 0, 3)[1]
            return p.from_le(data[:2]), data[2]

        def once() -> tuple[int, int]:
            self.write_packet(self._packet(servo_id, p.INST_PING, b""))
            _err, data = self._read_status([servo_id], [3], f"ping ID {servo_id}")[servo_id]
            return p.from_le(data[:2]), data[2]

        return self.transact(once, f"ping ID {servo_id}")

    def scan(self, ids: Iterable[int] = range(0, p.MAX_ID + 1)) -> dict[int, int]:
        """IDs that answer, with model numbers (Protocol 2.0: one broadcast ping via the SDK)."""
        found: dict[int, int] = {}
        wanted = set(ids)
        if self._v2:
            port = self._require_port()
            try:
                data, _result = self.handler.broadcastPing(port)
            except _PORT_ERRORS as exc:
                raise self._unplugged(exc) from exc
            return {i: int(v[0]) for i, v in data.items() if i in wanted}
        for sid in sorted(wanted):
            try:
                found[sid] = self.ping(sid)
            except PortUnavailableError:
                raise
            except CommunicationError:
                continue
        return found

    def _read_once(self, servo_id: int, address: int, size: int) -> tuple[int, bytes]:
        length = p.le_bytes(size, 2) if self._v2 else bytes((size,))
        self.write_packet(self._packet(servo_id, p.INST_READ, self._addr(address) + length))
        return self._read_status(
            [servo_id], [size], f"read {size} B @{address} from ID {servo_id}"
        )[servo_id]

    def read(self, servo_id: int, address: int, size: int) -> tuple[int, bytes]:
        """(error byte, data) of one servo's registers."""
        return self.transact(
            lambda: self._read_once(servo_id, address, size), f"read @{address} from {servo_id}"
        )

    def write(self, servo_id: int, address: int, data: bytes) -> int:
        """Write with a status reply; returns the servo's error byte."""

        def once() -> int:
            self.write_packet(self._packet(servo_id, p.INST_WRITE, self._addr(address) + data))
            return self._read_status([servo_id], [0], f"write @{address} to ID {servo_id}")[
                servo_id
            ][0]

        return self.transact(once, f"write @{address} to {servo_id}")

    def write_no_reply(self, servo_id: int, address: int, data: bytes) -> None:
        """Write without waiting for a status reply: to a servo whose Status Return Level
        answers reads only (a reply to a write would never come)."""
        self.transact(
            lambda: self.write_packet(
                self._packet(servo_id, p.INST_WRITE, self._addr(address) + data)
            ),
            f"write @{address} to {servo_id}",
        )

    def sync_write_packet(self, address: int, size: int, values: Mapping[int, bytes]) -> bytes:
        """The Sync Write packet for ``values`` (servo ID → ``size`` data bytes)."""
        head = self._addr(address) + (p.le_bytes(size, 2) if self._v2 else bytes((size,)))
        body = b"".join(bytes((sid,)) + data for sid, data in values.items())
        return self._packet(p.BROADCAST_ID, p.INST_SYNC_WRITE, head + body)

    def sync_write(self, address: int, size: int, values: Mapping[int, bytes]) -> bytes:
        """Broadcast Sync Write (no reply); returns the bytes sent."""
        packet = self.sync_write_packet(address, size, values)
        self.write_packet(packet)
        return packet

    def sync_read_packet(
        self, address: int, size: int, ids: Sequence[int], *, fast: bool = False
    ) -> bytes:
        """The Protocol 2.0 (Fast) Sync Read request for ``ids``: build it once, send it often."""
        if not self._v2:
            raise CommunicationError("Sync Read needs Protocol 2.0; use bulk_read/read")
        params = p.le_bytes(address, 2) + p.le_bytes(size, 2) + bytes(ids)
        inst = p.INST_FAST_SYNC_READ if fast else p.INST_SYNC_READ
        return p.build_v2(p.BROADCAST_ID, inst, params)

    def sync_read(
        self, address: int, size: int, ids: Sequence[int], *, fast: bool = False
    ) -> ReadResult:
        """Protocol 2.0 Sync Read (or Fast Sync Read: one combined reply) of ``ids``."""
        packet = self.sync_read_packet(address, size, ids, fast=fast)

        def once() -> ReadResult:
            self.write_packet(packet)
            if fast:
                errors, data = self._read_fast_block(ids, size)
                return {
                    sid: (int(e), row.tobytes())
                    for sid, e, row in zip(ids, errors, data, strict=True)
                }
            return self._read_status(ids, [size] * len(ids), "sync read")

        return self.transact(once, "fast sync read" if fast else "sync read")

    def sync_read_block(
        self, packet: bytes, ids: Sequence[int], size: int, *, fast: bool
    ) -> tuple[ByteArray, ByteArray]:
        """Send a request from :meth:`sync_read_packet` and return (error byte per servo,
        (N, size) data matrix), both in ``ids`` order; retried like every transaction."""

        def once() -> tuple[ByteArray, ByteArray]:
            self.write_packet(packet)
            if fast:
                return self._read_fast_block(ids, size)
            result = self._read_status(ids, [size] * len(ids), "sync read")
            return as_block(result, ids, size)

        return self.transact(once, "fast sync read" if fast else "sync read")

    def _read_fast_block(self, ids: Sequence[int], size: int) -> tuple[ByteArray, ByteArray]:
        n = len(ids)
        total = 8 + n * (size + 4)
        raw = self._read_exact(total, "fast sync read")
        if raw[:4] != p.HEADER_V2 or raw[4] != p.BROADCAST_ID or raw[7] != p.INST_STATUS:
            raise CommunicationError(f"bus {self.name}: fast sync read: bad reply header")
        if p.packet_length_v2(raw) != total:
            raise CommunicationError(f"bus {self.name}: fast sync read: bad reply length")
        if p.crc16_packet(raw[:-2]) != (raw[-2] | raw[-1] << 8):
            raise CommunicationError(f"bus {self.name}: fast sync read: CRC mismatch")
        # Per servo: ERR, ID, DATA…, CRC_L, CRC_H (the running CRC, checked above as a whole).
        rows = np.frombuffer(raw, dtype=np.uint8, count=n * (size + 4), offset=8).reshape(
            n, size + 4
        )
        got = rows[:, 1]
        if not np.array_equal(got, np.asarray(ids, dtype=np.uint8)):
            k = int(np.argmax(got != np.asarray(ids, dtype=np.uint8)))
            raise CommunicationError(
                f"bus {self.name}: fast sync read: expected ID {ids[k]}, got {int(got[k])}"
            )
        return rows[:, 0], rows[:, 2 : 2 + size]

    def bulk_read(self, items: Sequence[tuple[int, int, int]]) -> ReadResult:
        """Bulk Read of (servo ID, address, size) items; the SDK's GroupBulkRead is broken on
        Protocol 1.0 (TypeError), so the packet is built here for both protocols."""
        if self._v2:
            params = b"".join(
                bytes((sid,)) + p.le_bytes(a, 2) + p.le_bytes(n, 2) for sid, a, n in items
            )
        else:
            params = b"\x00" + b"".join(bytes((n, sid, a)) for sid, a, n in items)
        packet = self._packet(p.BROADCAST_ID, p.INST_BULK_READ, params)
        ids = [sid for sid, _, _ in items]
        sizes = [n for _, _, n in items]

        def once() -> ReadResult:
            self.write_packet(packet)
            return self._read_status(ids, sizes, "bulk read")

        return self.transact(once, "bulk read")


def as_block(result: ReadResult, ids: Sequence[int], size: int) -> tuple[ByteArray, ByteArray]:
    """A ReadResult as (error byte per servo, (N, size) data matrix) in ``ids`` order; a servo
    that answered with an error and no data gets a row of zeros."""
    errors = np.array([result[sid][0] for sid in ids], dtype=np.uint8)
    data = b"".join(result[sid][1].ljust(size, b"\0") for sid in ids)
    return errors, np.frombuffer(data, dtype=np.uint8).reshape(len(ids), size)


def buses_from_config(
    config: RobotConfig, ports: Mapping[str, str] | None = None, *, retries: int = 2
) -> dict[str, DynamixelBus]:
    """One (unopened) DynamixelBus per config bus: port from ``ports[bus name]`` or the bus's
    ``default_port``; protocol, baud rate and packet timeout from the config."""
    ports = ports or {}
    return {
        b.name: DynamixelBus(
            ports.get(b.name, b.default_port),
            protocol=b.protocol,
            baud_rate=b.baud_rate,
            packet_timeout_ms=config.hardware.packet_timeout_ms,
            retries=retries,
            name=b.name,
        )
        for b in config.buses
    }
