"""KeypointFormatError: a keypoint file that cannot be read, naming the file and the frame."""

from __future__ import annotations

from pathlib import Path

from robot_retarget.errors import MotionFormatError


class KeypointFormatError(MotionFormatError):
    """``path`` and ``frame`` (0-based, None when the whole file is wrong) as attributes."""

    def __init__(self, message: str, *, path: str | Path, frame: int | None = None) -> None:
        self.frame = frame
        where = message if frame is None else f"frame {frame}: {message}"
        super().__init__(where, path=path)
