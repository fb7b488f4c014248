"""The MotionSource interface: where live (or replayed) human frames come from.

A source delivers :class:`SourceFrame` objects on the canonical skeleton. Network sources
receive on their own thread into a bounded queue; the control loop calls :meth:`poll` once per
tick and never blocks. Everything a source refuses (malformed, oversized, out-of-order,
duplicate, NaN, wrong token, queue overflow) is counted in :class:`SourceStats`, never raised;
what the user must hear about at once (a sender whose every packet is dropped) is a warning
there too (:meth:`SourceStats.warn`).
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.skeleton import Skeleton

DEFAULT_QUEUE_FRAMES = 256
"""Frames a network source buffers between two polls before it drops the oldest."""

WARN_AFTER = 30  # consecutive packets a sender got wrong before a live warning
MAX_MESSAGE_CHARS = 200
_SENDER_FAULTS = frozenset(("oversized", "malformed", "nan", "degenerate", "auth"))
DROP_REASONS: tuple[str, ...] = (
    "oversized",
    "malformed",
    "out_of_order",
    "second_sender",
    "duplicate",
    "nan",
    "degenerate",
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
    """Counters of what a source accepted and dropped (by reason, see DROP_REASONS), and the
    warnings it raised. ``on_warning``, when set (the CLI sets it to its live report line),
    is called with each warning as it happens, possibly from the source's receiver thread."""

    received: int = 0
    accepted: int = 0
    dropped: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DROP_REASONS, 0))
    # The last drop's message per reason (what was wrong with the packet), for the summary.
    last_messages: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    on_warning: Callable[[str], None] | None = field(default=None, repr=False, compare=False)
    _rejected_streak: int = field(default=0, repr=False, compare=False)

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())

    def drop(self, reason: str, message: str | None = None) -> None:
        """Count a dropped packet. Packets the sender got wrong (malformed, NaN, oversized,
        a wrong token) that come :data:`WARN_AFTER` in a row raise a live warning with the
        last one's ``message``, again every ten times as many while it lasts."""
        self.dropped[reason] = self.dropped.get(reason, 0) + 1
        if message:  # a sender writes part of it (a 16 kB 'kind'): kept to a line
            if len(message) > MAX_MESSAGE_CHARS:
                message = message[: MAX_MESSAGE_CHARS - 1] + "…"
            self.last_messages[reason] = message
        if reason not in _SENDER_FAULTS:
            return
        self._rejected_streak += 1
        n = self._rejected_streak
        if n == WARN_AFTER or (n > WARN_AFTER and (n - WARN_AFTER) % (10 * WARN_AFTER) == 0):
            why = f": {message}" if message else ""
            self.warn(
                f"source: {n} packets in a row dropped as {reason}{why}; nothing from this "
                "sender reaches the robot until it is fixed"
            )

    def accept(self) -> None:
        """Count an accepted frame (and end a run of rejected packets)."""
        self.accepted += 1
        self._rejected_streak = 0

    def warn(self, message: str) -> None:
        """Record a warning and pass it on to ``on_warning`` (live) when set."""
        self.warnings.append(message)
        if self.on_warning is not None:
            self.on_warning(message)

    def summary(self) -> str:
        parts = [
            f"{k} {v}"
            + (f" — the last: {self.last_messages[k]}" if k in self.last_messages else "")
            for k, v in self.dropped.items()
            if v
        ]
        detail = f" ({'; '.join(parts)})" if parts else ""
        warned = (
            f"; {len(self.warnings)} warning(s), the last: {self.warnings[-1]}"
            if self.warnings
            else ""
        )
        return (
            f"source: {self.received} received, {self.accepted} accepted, "
            f"{self.dropped_total} dropped{detail}{warned}"
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
        # Set by put(), cleared by drain(): a waiting control loop wakes when a frame comes.
        self.arrived = threading.Event()

    def put(self, frame: SourceFrame) -> None:
        with self._lock:
            if len(self._items) >= self._max:
                self._items.popleft()
                self._stats.drop("queue_full")
            self._items.append(frame)
            self.arrived.set()

    def drain(self) -> list[SourceFrame]:
        with self._lock:
            out = list(self._items)
            self._items.clear()
            self.arrived.clear()
        return out


class SequenceFilter:
    """Accepts frames whose sequence number and timestamp both increase; counts the rest.

    The rule, per frame, against the last accepted one (``seq`` / ``t_s``):

    - the same sequence number: dropped as ``duplicate``;
    - sequence number and timestamp both larger: accepted;
    - the sender restarted, and the frame accepted as the first of a new stream, when its
      sequence number is 0 after a larger one, or when its sequence number went back *and*
      its timestamp went back by more than ``restart_backstep_s`` (default 0.5 s): the
      network delays a datagram by a few frames at most, a restarted sender's clock starts
      over. (A sender that restarted less than 0.5 s after its first frame is dropped until
      its sequence and clock pass the old ones, i.e. for less than 0.5 s.)
    - anything else: dropped as ``out_of_order`` (a late datagram; a sender that restarted its
      sequence numbers but not its clock; two senders on one port).
    - after a restart, a frame that continues the stream left behind (its sequence number
      and timestamp just above that stream's last, nearer than to the current one's) is a
      second sender on the port: dropped as ``second_sender``, with a warning. Two senders
      with different sequence and clock bases had otherwise passed as a restart at every
      switch, and the robot played both performers, alternating packet by packet.

    ``warn_after`` (default 30) consecutive ``out_of_order`` drops raise a warning through
    :meth:`SourceStats.warn` (printed live by the CLI), again every ``10 × warn_after``
    further drops while it lasts: a sender whose every packet is dropped is never silent.
    """

    def __init__(
        self, stats: SourceStats, *, restart_backstep_s: float = 0.5, warn_after: int = 30
    ) -> None:
        if warn_after < 1:
            raise ValueError(f"warn_after must be at least 1, got {warn_after}")
        self._stats = stats
        self.restart_backstep_s = restart_backstep_s
        self.warn_after = warn_after
        self.restarts = 0
        self._last_seq: int | None = None
        self._last_t: float | None = None
        self._streak = 0  # consecutive out_of_order drops
        self._left: tuple[int, float] | None = None  # the stream a restart left behind

    def _is_restart(self, seq: int, t_s: float) -> bool:
        if self._last_seq is None or self._last_t is None:
            return False
        if seq == 0 and self._last_seq > 0:
            return True
        return seq < self._last_seq and t_s < self._last_t - self.restart_backstep_s

    def _continues_left(self, seq: int, t_s: float) -> bool:
        """Whether the frame continues the stream the last restart left, rather than this."""
        if self._left is None or self._last_seq is None or self._last_t is None:
            return False
        left_seq, left_t = self._left
        if not (seq > left_seq and t_s > left_t):
            return False
        ahead = seq > self._last_seq and t_s > self._last_t
        return not ahead or seq - left_seq < seq - self._last_seq

    def accept(self, seq: int, t_s: float) -> bool:
        if self._continues_left(seq, t_s):
            self._left = (seq, t_s)
            self._stats.drop("second_sender")
            dropped = self._stats.dropped["second_sender"]
            if dropped == 3 or dropped % (10 * self.warn_after) == 0:
                self._stats.warn(
                    f"source: {dropped} packets dropped from a second sender on this "
                    f"port (seq {seq} at t {t_s:.3f} s, while following seq {self._last_seq} at "
                    f"t {self._last_t:.3f} s): stop the other sender, or give each its own port"
                )
            return False
        if self._left is not None and seq > self._left[0] and t_s > self._left[1]:
            self._left = None  # this stream has passed the one it left: nothing left behind
        if self._is_restart(seq, t_s):
            self.restarts += 1
            self._left = (self._last_seq, self._last_t)  # type: ignore[assignment]
        elif self._last_seq is not None and self._last_t is not None:
            if seq == self._last_seq:
                self._stats.drop("duplicate")
                return False
            if seq < self._last_seq or t_s <= self._last_t:
                self._stats.drop("out_of_order")
                self._streak += 1
                if self._streak == self.warn_after or (
                    self._streak > self.warn_after
                    and (self._streak - self.warn_after) % (10 * self.warn_after) == 0
                ):
                    self._stats.warn(
                        f"source: {self._streak} packets in a row dropped as out of order "
                        f"(seq {seq} at t {t_s:.3f} s, last accepted seq {self._last_seq} at "
                        f"t {self._last_t:.3f} s): if the sender restarted, restart its "
                        "timestamps too (or its sequence numbers at 0); or is a second sender "
                        "using this port?"
                    )
                return False
        self._streak = 0
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

    def wait_for_frame(self, timeout_s: float) -> bool | None:
        """Block until a frame arrives (True) or ``timeout_s`` passes (False); None: this
        source cannot be waited on (the caller sleeps instead)."""
        return None

    def describe(self) -> str:
        return type(self).__name__

    def report_lines(self) -> tuple[str, ...]:
        """What this source has to say at the end of a stream, beside its statistics."""
        return ()

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
