"""ReplaySource: a clip played back in real time (or ``speed`` × real time), optionally looped.

Pull-based, no thread: each poll returns the frames whose time has come since the previous
poll. Frame k of loop n has timestamp ``(n · T + k) / (fps · speed)`` (T frames per loop):
seconds of the clip *as played*, increasing across loops; ``recv_s`` is when it became due.
"""

from __future__ import annotations

import math

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.base import MotionSource, SourceFrame, SourceStats


class ReplaySource(MotionSource):
    def __init__(self, motion: HumanMotion, *, loop: bool = False, speed: float = 1.0) -> None:
        if not (math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be a positive number, got {speed}")
        self.motion = motion
        self.loop = loop
        self.speed = speed
        self.stats = SourceStats()
        self._t0: float | None = None
        self._next = 0  # index of the next frame to deliver, counting across loops
        self._running = False

    @property
    def skeleton(self) -> Skeleton:
        return self.motion.skeleton

    @property
    def nominal_fps(self) -> float:
        return self.motion.fps * self.speed

    @property
    def finished(self) -> bool:
        return not self.loop and self._next >= self.motion.num_frames

    def describe(self) -> str:
        name = self.motion.source_path or self.motion.name_family
        return f"replay {name} ({self.motion.num_frames} frames at {self.motion.fps:g} fps)"

    def start(self) -> None:
        self._t0 = None
        self._next = 0
        self._running = True

    def stop(self) -> None:
        self._running = False

    def poll(self, now_s: float) -> list[SourceFrame]:
        if not self._running:
            return []
        if self._t0 is None:
            self._t0 = now_s  # the clip starts at the first poll
        fps = self.motion.fps
        due = math.floor((now_s - self._t0) * self.speed * fps + 1e-9)
        total = self.motion.num_frames
        last = due if self.loop else min(due, total - 1)
        out: list[SourceFrame] = []
        while self._next <= last:
            k = self._next
            i = k % total
            t_s = k / (fps * self.speed)
            out.append(
                SourceFrame(
                    local_quats=self.motion.local_quats[i],
                    root_pos=self.motion.root_pos[i],
                    t_s=t_s,
                    seq=k,
                    recv_s=self._t0 + t_s,
                )
            )
            self._next += 1
        self.stats.received += len(out)
        self.stats.accepted += len(out)
        return out
