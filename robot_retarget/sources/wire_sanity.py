"""Tells of a sender that got the wire format's conventions wrong (numpy only).

A UDP sender writes canonical joints (Y up, X left, Z forward, in the order of
:data:`robot_retarget.skeleton.canonical.CANONICAL_JOINTS`) and quaternions w-x-y-z. A sender
that gets one of these wrong sends packets that decode and pass every check, and the robot is
driven into a pose no performer made (a user's sender: the joint list reversed, 48° off on
average; Z up, 15°; quaternions x-y-z-w, 45° with many joints at their limits). Two tells no
real performance shows for a second on end:

- positions: the head is not above the hips (Y) in most frames: a Z-up (or X-up) sender, or
  the joints in another order;
- rotations: most local rotations are far from none (|w| < 0.5 for most joints, every frame):
  the quaternions' scalar sent last (x-y-z-w). Most of a body's joints turn little from the
  rest pose in most motions; a rig whose rest pose is not the canonical T-pose shows it too.

Each tell must hold for a span of the sender's time (:data:`UPRIGHT_SPAN_S`,
:data:`ROTATIONS_SPAN_S`) and is warned once per stream, naming the convention to check. On the
70 CMU clips the head is at most 1.05 s on end less than 60° above the hips (05_06 bends
over), and at most 18 % of a frame's joints turn more than 120° (x-y-z-w: all of them).
Nothing is dropped: the frames are valid data, and a performer may lie down.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.canonical import Joint

UPRIGHT_SPAN_S = 3.0
"""Seconds on end the head must stay less than 60° above the hips before it is warned."""
ROTATIONS_SPAN_S = 1.0
"""Seconds on end most joints must be turned more than 120° before it is warned."""
_FAR_W = 0.5  # |w| below this: a local rotation of more than 120°
_MOST = 0.6  # the share of joints that makes "most"


class WireSanity:
    """``positions(p)`` / ``rotations(q)`` per accepted frame → a warning, once per stream."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """A new stream (a sender restart): the tells start over, and may warn again."""
        self._since: dict[str, float | None] = {"up": None, "w": None}
        self._warned: set[str] = set()

    def _held(self, tell: str, holds: bool, t_s: float, span_s: float) -> bool:
        """Whether ``tell`` has held for ``span_s`` of sender time (once per stream)."""
        if not holds:
            self._since[tell] = None
            return False
        start = self._since[tell]
        if start is None or t_s < start:
            self._since[tell] = start = t_s
        if t_s - start < span_s or tell in self._warned:
            return False
        self._warned.add(tell)
        return True

    def positions(self, p: FloatArray, t_s: float) -> str | None:
        """A (22, 3) frame of canonical positions at the sender's time ``t_s``."""
        up = p[Joint.Head] - p[Joint.Hips]
        low = bool(up[1] <= 0.5 * float(np.linalg.norm(up)))  # the head < 60° above the hips
        if not self._held("up", low, t_s, UPRIGHT_SPAN_S):
            return None
        return (
            f"source: for {UPRIGHT_SPAN_S:g} s the head has not been above the hips: position "
            "packets are canonical joints, Y up (X left, Z forward), in the order of "
            "robot_retarget.skeleton.canonical.CANONICAL_JOINTS (Hips first, Head sixth). A "
            "Z-up sender must send (x, z, -y); check too the joint order (unless the performer "
            "really is lying down)"
        )

    def rotations(self, q: FloatArray, t_s: float) -> str | None:
        """A (22, 4) frame of local rotations as sent (w-x-y-z) at the sender's time ``t_s``."""
        far = float(np.mean(np.abs(q[:, 0]) < _FAR_W)) > _MOST
        if not self._held("w", far, t_s, ROTATIONS_SPAN_S):
            return None
        return (
            f"source: for {ROTATIONS_SPAN_S:g} s most local rotations have |w| < {_FAR_W} (turned "
            "more than 120° from the rest pose): are the quaternions sent x-y-z-w? The wire "
            "format is w-x-y-z, scalar first, each joint's rotation from the canonical rest "
            "pose (robot_retarget.skeleton.canonical)"
        )
