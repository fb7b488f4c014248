"""PersonFrames: frames of detected people → one followed person's KeypointSequence."""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.sources.keypoints.person_choice import PersonTracker

Person = tuple[FloatArray, FloatArray, BoolArray]  # xy (17, 2), confidence (17,), valid (17,)
# Frames a file may skip between two of its frames (an hour at 30 fps is about 1e5): more is no
# gap in one recording, and would only fill memory with empty frames.
MAX_GAP_FRAMES = 100_000


class PersonFrames:
    """Collects frames; each frame keeps the person :class:`PersonTracker` follows, or nobody
    (every point missing)."""

    def __init__(self) -> None:
        self._tracker = PersonTracker()
        self._xy: list[FloatArray] = []
        self._conf: list[FloatArray] = []
        self._valid: list[BoolArray] = []

    def add(self, people: list[Person]) -> None:
        chosen = self._tracker.choose([(xy, v) for xy, _c, v in people])
        if chosen is None:
            self._xy.append(np.full((NUM_KEYPOINTS, 2), np.nan))
            self._conf.append(np.zeros(NUM_KEYPOINTS))
            self._valid.append(np.zeros(NUM_KEYPOINTS, dtype=bool))
            return
        xy, conf, valid = people[chosen]
        self._xy.append(np.where(valid[:, None], xy, np.nan))
        self._conf.append(conf)
        self._valid.append(valid.copy())

    def add_unseen(self, count: int) -> None:
        """``count`` frames the file has no entry for: nobody seen in them, so the frames after
        keep their time."""
        for _ in range(count):
            self.add([])

    def sequence(
        self, fps: float, *, source: str, image_size: tuple[float, float] | None = None
    ) -> KeypointSequence:
        return KeypointSequence(
            np.stack(self._xy),
            np.stack(self._conf),
            np.stack(self._valid),
            float(fps),
            source,
            image_size,
        )
