"""UdpSource: canonical-joint frames over UDP (wire format: robot_retarget.sources.wire).

Binding, tokens and the receiver thread: robot_retarget.sources.udp_datagram (the CLI refuses
--allow-remote without --token unless --insecure-no-token is given). Sequence numbers and
timestamps are checked by ``SequenceFilter`` (robot_retarget.sources.base; its docstring has
the rule for a sender that restarts). Rotation packets must carry unit quaternions; position
packets are turned into rotations here, after a tracker's frozen joints and swapped limbs are
undone and its jitter filtered (:class:`LivePositions`; ``clean_positions=False``: solved as
sent).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources import wire
from robot_retarget.sources.base import DEFAULT_QUEUE_FRAMES, SourceFrame
from robot_retarget.sources.position_cleanup import LivePositions
from robot_retarget.sources.udp_datagram import UdpDatagramSource
from robot_retarget.sources.wire_sanity import WireSanity

DEFAULT_PORT = 9750
_QUAT_NORM_TOL = 0.1  # a "unit" quaternion further off than this is a sender bug


class UdpSource(UdpDatagramSource):
    """Receives frames on ``host:port`` (port 0: any free port, see :attr:`address`)."""

    SCHEME = "udp"

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
        clean_positions: bool = True,
    ) -> None:
        skeleton = skeleton or default_canonical_skeleton()
        super().__init__(
            host,
            port,
            token=token,
            allow_remote=allow_remote,
            skeleton=skeleton,
            nominal_fps=nominal_fps,
            max_queue=max_queue,
            clock=clock,
        )
        # Position packets: frozen joints and swapped limbs undone, jitter filtered, then solved.
        self._positions = LivePositions(skeleton, clean=clean_positions)
        self._sanity = WireSanity()  # a sender's wrong axes, joint order or quaternion order

    def _sanity_warning(self, warning: str | None) -> None:
        if warning is not None:
            self.stats.warn(warning)

    @property
    def cleans_positions(self) -> bool:
        """Whether position packets are cleaned (frozen joints, swapped limbs, jitter)."""
        return self._positions.cleans

    def handle_packet(self, data: bytes, recv_s: float) -> SourceFrame | None:
        """Decode and check one datagram; queue and return the frame, or count the drop."""
        self.stats.received += 1
        try:
            pkt = wire.decode(data)
        except wire.WireError as exc:
            self.stats.drop(exc.reason, str(exc))
            return None
        if not self._authorised(pkt.token):
            return None
        if pkt.kind == wire.KIND_ROTATIONS:
            # Finite (the decoder checked) and near 1, so dividing by the norms is safe.
            norms = np.sqrt(np.einsum("ij,ij->i", pkt.values, pkt.values))[:, None]
            off = np.abs(norms - 1.0)
            if (off > _QUAT_NORM_TOL).any():
                worst = int(np.argmax(off))
                self.stats.drop(
                    "malformed",
                    f"quaternion {worst} has norm {float(norms[worst, 0]):.4g}, not 1 "
                    f"(tolerance {_QUAT_NORM_TOL})",
                )
                return None
            if not self._filter.accept(pkt.seq, pkt.t_s):
                return None
            local = pkt.values / norms
            root = pkt.root if pkt.root is not None else np.zeros(3)
            self._sanity_warning(self._sanity.rotations(local, pkt.t_s))
        else:
            if not self._filter.accept(pkt.seq, pkt.t_s):
                return None
            self._sanity_warning(self._sanity.positions(pkt.values, pkt.t_s))
            # The cleanup remembers the stream, so it sees accepted frames only, in order (a
            # restart shows as a timestamp that went back, and starts it over).
            local, root = self._positions(pkt.values, pkt.t_s)
        return self._deliver(SourceFrame(local, root, pkt.t_s, pkt.seq, recv_s))
