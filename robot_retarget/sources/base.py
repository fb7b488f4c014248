"""The MotionSource interface: where live (or replayed) human frames come from.

A source delivers :class:`SourceFrame` objects on the canonical skeleton. Network sources
receive on their own thread into a bounded queue; the control loop calls :meth:`poll` once per
tick and never blocks. Everything a source refuses (malformed, oversized, out-of-order,
duplicate, NaN, wrong token, queue overflow) is counted in :class:`SourceStats`, never raised.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass, field
from types import TracebackType

import numpy as np
import numpy.typing as npt

from robot_retarget.skeleton.skeleton import Skeleton

FloatArray = npt.NDArray[np.float64]

DEFAULT_QUEUE_FRAMES = 256
"""Frames a network source buffers between two polls before it drops the oldest."""

DROP_REASONS: tuple[str, ...] = (
    "oversized",
    "malformed",
    "out_of_order",
    "duplicate",
    "nan",
    "auth",
    "queue_full",
)


@dataclass(frozen=True)
class SourceFrame:
    """One human frame on the canonical skeleton.

    ``local_quats`` (22, 4) unit w-x-y-z, ``root_pos`` (3,) metres (Y up); ``t_s`` the sender's
    timestamp (seconds, any origin but monotonic per stream); ``seq`` the sender's sequence
    number; ``recv_s`` the receiver's monotonic clock when the frame arrived.
    """

    local_quats: FloatArray
    root_pos: FloatArray
    t_s: float
    seq: int
    recv_s: float


@dataclass
class SourceStats:
    """Counters of what a source accepted and dropped (by reason, see DROP_REASONS)."""

    received: int = 0
    accepted: int = 0
    dropped: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DROP_REASONS, 0))

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())

    def drop(self, reason: str) -> None:
        self.dropped[reason] = self.dropped.get(reason, 0) + 1

    def summary(self) -> str:
        parts = [f"{k} {v}" for k, v in self.dropped.items() if v]
        detail = f" ({', '.join(parts)})" if parts else ""
        return (
            f"source: {self.received} received, {self.accepted} accepted, "
            f"{self.dropped_total} dropped{detail}"
        )


class FrameQueue:
    """A bounded, thread-safe FIFO of frames; a full queue drops its oldest frame."""

    def __init__(self, stats: SourceStats, max_frames: int = DEFAULT_QUEUE_FRAMES) -> None:
        if max_frames < 1:
            raise ValueError(f"max_frames must be at least 1, got {max_frames}")
        self._items: deque[SourceFrame] = deque()
        self._max = max_frames
        self._lock = threading.Lock()
        self._stats = stats

    def put(self, frame: SourceFrame) -> None:
        with self._lock:
            if len(self._items) >= self._max:
                self._items.popleft()
                self._stats.drop("queue_full")
            self._items.append(frame)

    def drain(self) -> list[SourceFrame]:
        with self._lock:
            out = list(self._items)
            self._items.clear()
        return out


class SequenceFilter:
    """Accepts frames whose sequence number and timestamp increase; counts the rest.

    Sequence number 0 after a larger one starts a new stream (the sender restarted).
    """

    def __init__(self, stats: SourceStats) -> None:
        self._stats = stats
        self._last_seq: int | None = None
        self._last_t: float | None = None

    def accept(self, seq: int, t_s: float) -> bool:
        restart = seq == 0 and self._last_seq is not None and self._last_seq > 0
        if self._last_seq is not None and self._last_t is not None and not restart:
            if seq == self._last_seq:
                self._stats.drop("duplicate")
                return False
            if seq < self._last_seq or t_s <= self._last_t:
                self._stats.drop("out_of_order")
                return False
        self._last_seq = seq
        self._last_t = t_s
        return True


class MotionSource(ABC):
    """Start, poll frames, stop. A context manager: ``with source:`` starts and always stops.

    ``skeleton`` is the performer's canonical skeleton (rest offsets, metres): the network's
    source skeleton. ``finished`` becomes True when a finite source has nothing more to give.
    """

    stats: SourceStats

    @property
    @abstractmethod
    def skeleton(self) -> Skeleton:
        """The performer's canonical skeleton (may be known only after the first frame)."""

    @property
    @abstractmethod
    def nominal_fps(self) -> float:
        """Expected input frame rate (Hz), used to tell late frames from on-time ones."""

    @abstractmethod
    def start(self) -> None:
        """Open sockets / threads; frames may arrive from now on."""

    @abstractmethod
    def poll(self, now_s: float) -> list[SourceFrame]:
        """Frames that arrived since the last poll (oldest first); never blocks."""

    @abstractmethod
    def stop(self) -> None:
        """Close sockets and join threads. Safe to call twice."""

    @property
    def finished(self) -> bool:
        return False

    def describe(self) -> str:
        return type(self).__name__

    def __enter__(self) -> MotionSource:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
