"""Simulated time and a scripted source for tests of the control loop: no test that uses them
waits for the wall clock."""

from __future__ import annotations

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.sources.base import MotionSource, SourceFrame, SourceStats


class FakeClock:
    """``now`` for the loop and the simulator; ``sleep`` advances it instead of waiting."""

    def __init__(self, t0_s: float = 100.0) -> None:
        self.t = t0_s

    def now(self) -> float:
        return self.t

    def sleep(self, dt_s: float) -> None:
        self.t += max(dt_s, 0.0)


class ScriptedSource(MotionSource):
    """Frames of a clip, each delivered at its own clip time, except inside ``gaps`` (clip
    seconds, half-open) where the sender is silent. Polled with the loop's (fake) clock."""

    def __init__(
        self, motion: HumanMotion, gaps: tuple[tuple[float, float], ...] = (), *, live: bool = False
    ) -> None:
        self.motion = motion
        self.gaps = gaps
        self.live = live  # a live sender never finishes: after its last frame it is just silent
        self.stats = SourceStats()
        self._t0: float | None = None
        self._next = 0

    @property
    def skeleton(self) -> Skeleton:
        return self.motion.skeleton

    @property
    def nominal_fps(self) -> float:
        return self.motion.fps

    @property
    def finished(self) -> bool:
        return not self.live and self._next >= self.motion.num_frames

    def start(self) -> None:
        self._t0 = None
        self._next = 0

    def stop(self) -> None:
        pass

    def poll(self, now_s: float) -> list[SourceFrame]:
        if self._t0 is None:
            self._t0 = now_s
        out = []
        while self._next < self.motion.num_frames:
            t = self._next / self.motion.fps
            if self._t0 + t > now_s:
                break
            if not any(a <= t < b for a, b in self.gaps):
                m, k = self.motion, self._next
                out.append(SourceFrame(m.local_quats[k], m.root_pos[k], t, k, self._t0 + t))
            self._next += 1
        self.stats.received += len(out)
        self.stats.accepted += len(out)
        return out
