"""KeypointFormatError: a keypoint file that cannot be read, naming the file and the frame."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from robot_retarget.errors import MotionFormatError


def json_fault(text: str) -> tuple[Any, str | None]:
    """(the document, None), or (None, what is wrong with ``text`` as JSON)."""
    try:
        return json.loads(text), None
    except json.JSONDecodeError as exc:
        where = f"line {exc.lineno}, " if exc.lineno > 1 else ""
        return None, f"not a JSON document ({exc.msg} at {where}column {exc.colno})"
    except RecursionError:
        return None, "not a JSON document (nested too deeply)"
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        return None, f"not a JSON document ({str(exc).split(';')[0]})"


def read_text(path: Path, frame: int | None = None) -> str:
    """A keypoint file's UTF-8 text (a byte-order mark, as Windows editors write, dropped);
    KeypointFormatError when it is not UTF-8."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise KeypointFormatError(
            f"not UTF-8 text ({exc.reason} at byte {exc.start}): keypoint files are UTF-8",
            path=path,
            frame=frame,
        ) from None


def parse_json(
    text: str, path: str | Path, frame: int | None = None, line: int | None = None
) -> Any:
    """``text`` as JSON, or KeypointFormatError naming the file (and frame, and the file's
    ``line`` for a document on one line) and the fault."""
    doc, fault = json_fault(text)
    if fault is not None:
        raise KeypointFormatError(fault, path=path, frame=frame, line=line)
    return doc


class KeypointFormatError(MotionFormatError):
    """``path`` and ``frame`` (0-based, None when the whole file is wrong) as attributes."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path,
        frame: int | None = None,
        line: int | None = None,
    ) -> None:
        self.frame = frame
        where = message if frame is None else f"frame {frame}: {message}"
        super().__init__(where, path=path, line=line)
