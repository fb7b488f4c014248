"""UdpDatagramSource: what every live UDP source shares, one datagram per frame.

Binds 127.0.0.1 unless ``allow_remote`` (the CLI's explicit flag); with a ``token`` set, a
packet without it is dropped (compared in constant time). A receiver thread hands each datagram
to ``handle_packet``, which decodes, checks and queues it; nothing a sender does can raise in,
or stall, the control loop. Subclasses say what a datagram holds (robot_retarget.sources.udp:
canonical joints; robot_retarget.sources.keypoints.udp_keypoints: 2D keypoints).
"""

from __future__ import annotations

import errno
import hmac
import ipaddress
import socket
from abc import abstractmethod
from collections.abc import Callable
from typing import ClassVar

from robot_retarget.errors import SourceError
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.base import SequenceFilter, SourceFrame
from robot_retarget.sources.socket_source import SocketSource

RECV_BYTES = 65536  # larger than any valid packet, so oversized ones are seen whole


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


class UdpDatagramSource(SocketSource):
    """Receives datagrams on ``host:port`` (port 0: any free port, see :attr:`address`)."""

    SCHEME: ClassVar[str]  # the URL scheme ``describe`` prints, e.g. "udp"

    def __init__(
        self,
        host: str,
        port: int,
        *,
        token: str,
        allow_remote: bool,
        skeleton: Skeleton,
        nominal_fps: float,
        max_queue: int,
        clock: Callable[[], float],
    ) -> None:
        check_bind_address(host, allow_remote, "UDP bind")
        self.host = host
        self.port = port
        self._bound: tuple[str, int] | None = None
        self.token = token
        super().__init__(max_queue)
        self._skeleton = skeleton
        self._fps = nominal_fps
        self._clock = clock
        self._filter = SequenceFilter(self.stats)

    @property
    def skeleton(self) -> Skeleton:
        return self._skeleton

    @property
    def nominal_fps(self) -> float:
        return self._fps

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port) once started (and after it stops: the summary names the port
        a port 0 was given); before, the one asked for."""
        return self._bound or (self.host, self.port)

    def describe(self) -> str:
        host, port = self.address
        return f"{self.SCHEME}://{host}:{port}" + (" (token required)" if self.token else "")

    def start(self) -> None:
        if self.started:  # opened early (stream binds before the robot connects)
            return
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.bind((self.host, self.port))
        except OSError as exc:
            sock.close()
            raise SourceError(
                f"cannot bind UDP {self.host}:{self.port} ({exc}); {_bind_advice(exc)}"
            ) from exc
        host, port = sock.getsockname()[:2]
        self._bound = (str(host), int(port))  # kept: the port stays known once the socket closes
        self._start_receiver(sock, f"{self.SCHEME}-source")

    def _run(self) -> None:
        sock = self._sock
        while sock is not None and not self._stop.is_set():
            try:
                data = sock.recv(RECV_BYTES)
            except TimeoutError:
                continue
            except OSError:
                return  # socket closed by stop()
            try:
                self.handle_packet(data, self._clock())
            except Exception as exc:  # no packet may stop the receiver: count it, go on
                self.stats.drop("malformed", f"unreadable packet ({type(exc).__name__}: {exc})")

    def _authorised(self, token: str) -> bool:
        """False (and the drop counted) when a token is required and ``token`` is not it."""
        # surrogatepass: a JSON token may hold lone surrogates, which plain UTF-8 refuses.
        sent, wanted = (t.encode("utf-8", "surrogatepass") for t in (token, self.token))
        if self.token and not hmac.compare_digest(sent, wanted):
            self.stats.drop(
                "auth",
                "the packet carries no token; --token requires one"
                if not token
                else "the packet's token is not the one --token set",
            )
            return False
        return True

    def _deliver(self, frame: SourceFrame) -> SourceFrame:
        self.stats.accept()
        self._queue.put(frame)
        return frame

    @abstractmethod
    def handle_packet(self, data: bytes, recv_s: float) -> SourceFrame | None:
        """Decode and check one datagram; queue and return the frame, or count the drop."""


def _bind_advice(exc: OSError) -> str:
    """What to do when a bind fails, by its cause."""
    if exc.errno == errno.EADDRINUSE:
        return "is another stream running? choose another port"
    if exc.errno == errno.EADDRNOTAVAIL:
        return (
            "that address is not one of this machine's: bind one of its own addresses, or "
            "0.0.0.0 for all of them (with --allow-remote)"
        )
    if exc.errno == errno.EACCES:
        return "ports below 1024 need administrator rights: choose a port of 1024 or more"
    return "choose another address or port"
