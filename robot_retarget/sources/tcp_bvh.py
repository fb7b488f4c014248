"""TcpBvhSource: a BVH motion stream over TCP, as mocap software broadcasts it.

The sender (the server: motion-capture software) first sends a complete BVH header —
``HIERARCHY … MOTION``, ``Frames: N`` (any N, ignored) and ``Frame Time: dt`` — then one line
of channel values per frame, forever. We connect as a client. The header is read in
:meth:`start` (so the performer's skeleton is known before streaming begins) and mapped onto
the canonical skeleton with the same loader as files (every naming family it knows); each
frame line is then converted with the mapping fixed by the header. Frame k gets timestamp
``k · dt`` and sequence number k. Lines with the wrong number of values, non-numbers or NaN are
dropped and counted; an overlong line is dropped as oversized.
"""

from __future__ import annotations

import dataclasses
import math
import re
import socket
import time
from collections.abc import Callable

import numpy as np

from robot_retarget.errors import MotionFormatError, SourceError
from robot_retarget.motion.bvh import FRAME_TIME_RE, MAX_ABS_VALUE, BvhClip, parse_bvh
from robot_retarget.motion.canonicalize import canonicalize
from robot_retarget.motion.frame_rate import FPS_RANGE, plausible_fps
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.base import (
    DEFAULT_QUEUE_FRAMES,
    SourceFrame,
)
from robot_retarget.sources.socket_source import SocketSource
from robot_retarget.sources.udp_datagram import check_bind_address

MAX_HEADER_BYTES = 1 << 20
MAX_LINE_BYTES = 1 << 16
_PACE_WINDOW_S = 2.0  # wall seconds of frames judged at once
_PACE_FACTOR = 1.5  # frames' time over wall time beyond which the sender is too fast


def split_header(text: str) -> tuple[str, float, int] | None:
    """(header text up to MOTION, frame time s, characters consumed) once the ``Frame Time``
    line is complete; None while more text is needed."""
    lines = text.split("\n")
    consumed = 0
    motion = False
    for i, raw in enumerate(lines[:-1]):  # the last piece may be an incomplete line
        consumed += len(raw) + 1
        line = raw.strip()
        if line.upper() == "MOTION":
            motion = True
            header_end = consumed
        elif motion and (m := FRAME_TIME_RE.match(line)) is not None:  # as the file reader
            try:
                dt = float(m.group(1))
            except ValueError:
                raise MotionFormatError(f"bad Frame Time line {line!r}", line=i + 1) from None
            if not (math.isfinite(dt) and dt > 0.0):
                raise MotionFormatError(f"Frame Time must be positive, got {dt}", line=i + 1)
            if not plausible_fps(1.0 / dt):
                raise MotionFormatError(
                    f"Frame Time {dt:g} s is {1.0 / dt:.3g} frames per second; motion is "
                    f"streamed at {FPS_RANGE}",
                    line=i + 1,
                )
            return text[:header_end], dt, consumed
    return None


class TcpBvhSource(SocketSource):
    def __init__(
        self,
        host: str,
        port: int,
        *,
        allow_remote: bool = False,
        connect_timeout_s: float = 5.0,
        max_queue: int = DEFAULT_QUEUE_FRAMES,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        check_bind_address(host, allow_remote, "tcp-bvh server")
        self.host = host
        self.port = port
        self.connect_timeout_s = connect_timeout_s
        super().__init__(max_queue)
        self._clock = clock
        self._template: BvhClip | None = None
        self._first: HumanMotion | None = None
        self._dt = 0.0
        self._count = 0
        self._pace_start: tuple[float, float] | None = None  # (wall s, frames' s) judged from
        self._pace_warned = False
        self._pending = b""
        self._closed = False
        self.error: str | None = None  # why the stream ended early, if it did

    @property
    def skeleton(self) -> Skeleton:
        if self._first is None:
            raise SourceError("tcp-bvh source: start() first (the skeleton comes in the header)")
        return self._first.skeleton

    @property
    def nominal_fps(self) -> float:
        return 1.0 / self._dt if self._dt > 0 else 60.0

    @property
    def finished(self) -> bool:
        return self._closed

    def describe(self) -> str:
        return f"tcp-bvh://{self.host}:{self.port}"

    def start(self) -> None:
        if self.started:  # opened early (stream binds before the robot connects)
            return
        try:
            sock = socket.create_connection((self.host, self.port), timeout=self.connect_timeout_s)
        except OSError as exc:
            raise SourceError(
                f"cannot connect to the BVH stream at {self.host}:{self.port} ({exc}); is the "
                "mocap software broadcasting BVH on that port?"
            ) from exc
        try:
            rest = self._read_header(sock)
        except BaseException:
            sock.close()
            raise
        self._pending = rest
        self._start_receiver(sock, "tcp-bvh-source")

    def _read_header(self, sock: socket.socket) -> bytes:
        data = b""
        deadline = time.monotonic() + self.connect_timeout_s
        while True:
            text = data.decode("utf-8", errors="replace")
            try:
                found = split_header(text)
            except MotionFormatError as exc:
                raise SourceError(f"tcp-bvh header from {self.host}:{self.port}: {exc}") from exc
            if found is not None:
                break
            if len(data) > MAX_HEADER_BYTES:
                raise SourceError(f"tcp-bvh header longer than {MAX_HEADER_BYTES} bytes; not BVH?")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise SourceError(
                    f"no complete BVH header from {self.host}:{self.port} within "
                    f"{self.connect_timeout_s:g} s"
                )
            sock.settimeout(remaining)
            try:
                chunk = sock.recv(65536)
            except OSError as exc:
                raise SourceError(f"tcp-bvh stream failed while reading the header: {exc}") from exc
            if not chunk:
                raise SourceError("tcp-bvh stream closed before the header was complete")
            data += chunk
        header, dt, consumed = found
        try:
            # One zero row: the parser wants a frame. Its width counts the channels each
            # CHANNELS line names (the parser checks them against the declared counts).
            listed = re.findall(r"CHANNELS\s+\d+([^\n]*)", header, re.IGNORECASE)
            width = sum(len(names.split()) for names in listed)
            row = " ".join(["0"] * width)
            probe = parse_bvh(header + f"Frames: 1\nFrame Time: 1\n{row}", path=self.describe())
        except MotionFormatError as exc:
            raise SourceError(f"tcp-bvh header is not valid BVH: {exc}") from exc
        n_channels = sum(len(c) for c in probe.channels)
        self._template = dataclasses.replace(
            probe, frame_time_s=dt, motion=np.zeros((1, n_channels)), path=self.describe()
        )
        try:
            self._first = canonicalize(self._template, drop_tpose=False)
        except MotionFormatError as exc:
            raise SourceError(f"tcp-bvh skeleton cannot be mapped: {exc}") from exc
        self._dt = dt
        return text[consumed:].encode("utf-8")  # frame lines that came with the header

    def _run(self) -> None:
        sock = self._sock
        pending, self._pending = self._pending, b""
        if pending:
            self.feed(pending, self._clock())
        while sock is not None and not self._stop.is_set():
            try:
                chunk = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as exc:
                self._ended(f"connection lost: {exc}")
                break
            if not chunk:
                self._ended("the sender closed the stream")
                break
            self.feed(chunk, self._clock())
        self._closed = True

    def _ended(self, why: str) -> None:
        """Say (live, and in the summary) why the stream ended early."""
        if self._pending.strip():
            why += f"; its last frame was cut short ({len(self._pending)} bytes, not used)"
        self.error = why
        self.stats.warn(f"source: tcp-bvh {why}")

    def feed(self, data: bytes, recv_s: float) -> list[SourceFrame]:
        """Process received bytes (complete lines become frames); returns the new frames."""
        buf = self._pending + data
        lines = buf.split(b"\n")
        self._pending = lines.pop()
        if len(self._pending) > MAX_LINE_BYTES:
            self.stats.received += 1
            self.stats.drop("oversized", f"a frame line longer than {MAX_LINE_BYTES} bytes")
            self._pending = b""
        rows: list[np.ndarray] = []
        template = self._template
        if template is None:
            return []
        width = template.motion.shape[1]
        for raw in lines:
            if not raw.strip():
                continue
            self.stats.received += 1
            if len(raw) > MAX_LINE_BYTES:
                self.stats.drop("oversized", f"a frame line longer than {MAX_LINE_BYTES} bytes")
                continue
            try:
                values = np.array(raw.split(), dtype=np.float64)
            except ValueError:
                self.stats.drop("malformed", "a frame line holds something other than numbers")
                continue
            if values.shape != (width,):
                self.stats.drop(
                    "malformed",
                    f"a frame line has {values.size} values, the header declares {width} channels",
                )
                continue
            if not np.all(np.isfinite(values)):
                self.stats.drop("nan", "a frame line holds NaN or infinite values")
                continue
            if (np.abs(values) > MAX_ABS_VALUE).any():
                self.stats.drop(
                    "malformed", f"a frame line holds a value beyond ±{MAX_ABS_VALUE:g}"
                )
                continue
            rows.append(values)
        if not rows:
            return []
        first = self._first
        if first is None:
            return []
        try:
            clip = dataclasses.replace(template, motion=np.stack(rows))
            motion = canonicalize(
                clip,
                unit=first.unit,
                drop_tpose=False,
                up_axis=first.up_axis,
                family=first.name_family,
            )
        except (MotionFormatError, ValueError) as exc:
            for _ in rows:  # e.g. angles so large the rotations are not finite
                self.stats.drop("malformed", f"frames that cannot be retargeted: {exc}")
            return []
        frames = []
        for i in range(motion.num_frames):
            k = self._count
            frame = SourceFrame(motion.local_quats[i], motion.root_pos[i], k * self._dt, k, recv_s)
            self._count += 1
            self.stats.accept()
            self._queue.put(frame)
            frames.append(frame)
        self._check_pace(recv_s)
        return frames

    def _check_pace(self, recv_s: float) -> None:
        """Warn once when frames come faster than their Frame Time says: each frame is stamped
        k · Frame Time, so a sender at three times its rate ran the performer three times as
        fast, and said nothing (the safety report blamed a late loop)."""
        frames_time = self._count * self._dt
        if self._pace_start is None:
            self._pace_start = (recv_s, frames_time)
            return
        wall = recv_s - self._pace_start[0]
        sent = frames_time - self._pace_start[1]
        if wall >= _PACE_WINDOW_S and not self._pace_warned:
            if sent > _PACE_FACTOR * wall:
                self._pace_warned = True
                self.stats.warn(
                    f"source: tcp-bvh frames come {sent / wall:.1f}× faster than their Frame "
                    f"Time ({self._dt:g} s) says: the performer plays that much faster than "
                    "life; send one frame per Frame Time (or set Frame Time to the rate you send)"
                )
            self._pace_start = (recv_s, frames_time)
