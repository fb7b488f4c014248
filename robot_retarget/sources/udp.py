"""UdpSource: canonical-joint frames over UDP (wire format: robot_retarget.sources.wire).

Binds 127.0.0.1 by default; any other address needs ``allow_remote=True`` (the CLI's explicit
flag), and then a shared ``token`` is strongly advised (the CLI refuses --allow-remote without
--token unless --insecure-no-token is given): packets without the right token are dropped.
Sequence numbers and timestamps are checked by ``SequenceFilter`` (robot_retarget.sources.base;
its docstring has the rule for a sender that restarts). A receiver thread decodes, checks and
converts each datagram and puts frames in a bounded queue; nothing a sender does can raise in,
or stall, the control loop.
"""

from __future__ import annotations

import hmac
import ipaddress
import socket
import time
from collections.abc import Callable

import numpy as np

from robot_retarget.errors import SourceError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources import wire
from robot_retarget.sources.base import (
    DEFAULT_QUEUE_FRAMES,
    SequenceFilter,
    SourceFrame,
)
from robot_retarget.sources.from_positions import PositionsToRotations
from robot_retarget.sources.socket_source import SocketSource

DEFAULT_PORT = 9750
_RECV_BYTES = 65536  # larger than any valid packet, so oversized ones are seen whole
_QUAT_NORM_TOL = 0.1  # a "unit" quaternion further off than this is a sender bug


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and 'localhost'."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_bind_address(host: str, allow_remote: bool, what: str) -> None:
    """Refuse a non-loopback address unless the user asked for it explicitly."""
    if not is_loopback(host) and not allow_remote:
        raise SourceError(
            f"{what} address {host} is not loopback; live sources bind 127.0.0.1 by default. "
            "Pass --allow-remote with --token SECRET (or --insecure-no-token) to accept other "
            "hosts"
        )


class UdpSource(SocketSource):
    """Receives frames on ``host:port`` (port 0: any free port, see :attr:`address`)."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        *,
        token: str = "",
        allow_remote: bool = False,
        skeleton: Skeleton | None = None,
        nominal_fps: float = 60.0,
        max_queue: int = DEFAULT_QUEUE_FRAMES,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        check_bind_address(host, allow_remote, "UDP bind")
        self.host = host
        self.port = port
        self.token = token
        super().__init__(max_queue)
        self._skeleton = skeleton or default_canonical_skeleton()
        self._fps = nominal_fps
        self._clock = clock
        self._filter = SequenceFilter(self.stats)
        self._positions = PositionsToRotations(self._skeleton)

    @property
    def skeleton(self) -> Skeleton:
        return self._skeleton

    @property
    def nominal_fps(self) -> float:
        return self._fps

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port); valid after start()."""
        if self._sock is None:
            return (self.host, self.port)
        host, port = self._sock.getsockname()[:2]
        return (str(host), int(port))

    def describe(self) -> str:
        host, port = self.address
        return f"udp://{host}:{port}" + (" (token required)" if self.token else "")

    def start(self) -> None:
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.bind((self.host, self.port))
        except OSError as exc:
            sock.close()
            raise SourceError(
                f"cannot bind UDP {self.host}:{self.port} ({exc}); is another stream running? "
                "choose another port"
            ) from exc
        self._start_receiver(sock, "udp-source")

    def _run(self) -> None:
        sock = self._sock
        while sock is not None and not self._stop.is_set():
            try:
                data = sock.recv(_RECV_BYTES)
            except TimeoutError:
                continue
            except OSError:
                return  # socket closed by stop()
            self.handle_packet(data, self._clock())

    def handle_packet(self, data: bytes, recv_s: float) -> SourceFrame | None:
        """Decode and check one datagram; queue and return the frame, or count the drop."""
        self.stats.received += 1
        try:
            pkt = wire.decode(data)
        except wire.WireError as exc:
            self.stats.drop(exc.reason)
            return None
        if self.token and not hmac.compare_digest(pkt.token.encode(), self.token.encode()):
            self.stats.drop("auth")
            return None
        if pkt.kind == wire.KIND_ROTATIONS:
            norms = np.linalg.norm(pkt.values, axis=-1)
            if np.any(np.abs(norms - 1.0) > _QUAT_NORM_TOL):
                self.stats.drop("malformed")
                return None
            local = quat.normalize(pkt.values)
            root = pkt.root if pkt.root is not None else np.zeros(3)
        else:
            local, root = self._positions.solve(pkt.values)
        if not self._filter.accept(pkt.seq, pkt.t_s):
            return None
        frame = SourceFrame(local, root, pkt.t_s, pkt.seq, recv_s)
        self.stats.accepted += 1
        self._queue.put(frame)
        return frame
