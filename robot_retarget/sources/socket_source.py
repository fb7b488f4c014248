"""A live source whose socket is read by a background thread into a bounded queue.

The control loop never touches the socket: ``poll`` only drains frames the receiver thread has
already decoded, so a slow or hostile sender can never stall it.
"""

from __future__ import annotations

import socket
import threading
from abc import abstractmethod

from robot_retarget.sources.base import FrameQueue, MotionSource, SourceFrame, SourceStats

# Receive timeout: how quickly the receiver thread notices stop().
RECV_TIMEOUT_S = 0.05


class SocketSource(MotionSource):
    """Owns the socket, the receiver thread and the frame queue; subclasses open the socket
    (``start``) and decode what arrives (``_run``)."""

    def __init__(self, max_queue: int) -> None:
        self.stats = SourceStats()
        self._queue = FrameQueue(self.stats, max_queue)
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    @property
    def started(self) -> bool:
        """The socket is open and read (``start`` has run, ``stop`` not yet)."""
        return self._thread is not None

    def _start_receiver(self, sock: socket.socket, name: str) -> None:
        """Keep ``sock`` and start the thread that runs ``_run`` until stop()."""
        sock.settimeout(RECV_TIMEOUT_S)
        self._sock = sock
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @abstractmethod
    def _run(self) -> None:
        """Receiver thread: read ``self._sock`` until ``self._stop`` is set."""

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def poll(self, now_s: float) -> list[SourceFrame]:
        return self._queue.drain()

    def wait_for_frame(self, timeout_s: float) -> bool | None:
        return self._queue.arrived.wait(max(0.0, timeout_s))
