"""KeypointFormatError: a keypoint file that cannot be read, naming the file and the frame."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from robot_retarget.errors import MotionFormatError


def parse_json(text: str, path: str | Path, frame: int | None = None) -> Any:
    """``text`` as JSON, or KeypointFormatError naming the file (and frame) and the fault."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        where = f"line {exc.lineno}, " if exc.lineno > 1 else ""
        reason = f"{exc.msg} at {where}column {exc.colno}"
    except RecursionError:
        reason = "nested too deeply"
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        reason = str(exc).split(";")[0]
    raise KeypointFormatError(f"not a JSON document ({reason})", path=path, frame=frame)


class KeypointFormatError(MotionFormatError):
    """``path`` and ``frame`` (0-based, None when the whole file is wrong) as attributes."""

    def __init__(self, message: str, *, path: str | Path, frame: int | None = None) -> None:
        self.frame = frame
        where = message if frame is None else f"frame {frame}: {message}"
        super().__init__(where, path=path)
