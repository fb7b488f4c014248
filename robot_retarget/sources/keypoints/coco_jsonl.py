"""COCO-17 keypoints as JSON lines: one frame per line (RTMPose, YOLO-pose, ViTPose output).

Points in COCO-17 order (robot_retarget.keypoints.coco17: nose, eyes, ears, shoulders,
elbows, wrists, hips, knees, ankles; left before right), pixel coordinates. Each line:

    {"frame": 0, "t": 0.0, "people": [{"keypoints": [[x, y], ... 17],
                                        "keypoint_scores": [s, ... 17]}, ...]}

Each person's points may be given as MMPose writes them (``keypoints`` as 17 [x, y] pairs and
``keypoint_scores``; MMPose calls the list ``instances``, accepted too), as 17 [x, y, score]
triples (YOLO-pose's ``keypoints.data``), or as the COCO annotation's flat list of 51 values.
``frame`` and ``t`` are optional; the first line may carry ``"fps"`` (else 30 or the
caller's). A score is a confidence in [0, 1]; a point below the threshold is missing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS
from robot_retarget.keypoints.sequence import DEFAULT_MIN_CONFIDENCE, KeypointSequence
from robot_retarget.motion.frame_rate import FPS_RANGE, plausible_fps
from robot_retarget.sources.keypoints.errors import KeypointFormatError, parse_json
from robot_retarget.sources.keypoints.frames import MAX_GAP_FRAMES, Person, PersonFrames


class CocoPersonError(ValueError):
    """A person entry that is not COCO-17 (message says what was found)."""


def parse_coco_person(person: Any, min_confidence: float) -> Person:
    """One person object (any of the module docstring's forms) → xy, confidence, valid."""
    if not isinstance(person, dict) or "keypoints" not in person:
        raise CocoPersonError("needs a 'keypoints' entry")
    try:
        kp = np.asarray(person["keypoints"], dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise CocoPersonError("'keypoints' is not a numeric array") from None
    scores: FloatArray
    if kp.shape == (NUM_KEYPOINTS * 3,):
        kp = kp.reshape(NUM_KEYPOINTS, 3)
    if kp.shape == (NUM_KEYPOINTS, 3):
        xy, scores = kp[:, :2].copy(), kp[:, 2].copy()
    elif kp.shape == (NUM_KEYPOINTS, 2):
        if "keypoint_scores" not in person:
            raise CocoPersonError("17 [x, y] pairs need 'keypoint_scores'")
        try:
            scores = np.asarray(person["keypoint_scores"], dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise CocoPersonError("'keypoint_scores' is not a numeric array") from None
        if scores.shape != (NUM_KEYPOINTS,):
            raise CocoPersonError(f"'keypoint_scores' has shape {scores.shape}, expected (17,)")
        xy = kp.copy()
    else:
        raise CocoPersonError(
            f"'keypoints' has shape {kp.shape}; COCO-17 needs 17 [x, y] pairs (+ "
            "'keypoint_scores'), 17 [x, y, score] triples or 51 values"
        )
    valid = np.isfinite(xy).all(axis=1) & np.isfinite(scores) & (scores >= min_confidence)
    return xy, np.nan_to_num(scores), valid


def people_of(obj: dict[str, Any]) -> Any:
    return obj["people"] if "people" in obj else obj.get("instances")


def read_coco_jsonl(
    path: Path, *, fps: float | None = None, min_confidence: float = DEFAULT_MIN_CONFIDENCE
) -> KeypointSequence:
    """A COCO-17 JSON-lines file → the followed person's sequence; errors name the file, its
    line and the frame. A line's ``frame`` number (else its ``t`` seconds at the frame rate)
    places it in time: frames skipped between two lines are frames nobody was seen in, so the
    rest keep their time; without either, each line is the next frame. Blank lines are not
    frames."""
    frames = PersonFrames()
    rate = fps
    index = 0  # the next frame's position in the sequence
    first: tuple[float, str] | None = None  # the first line's frame number or time
    line_no = 0
    with path.open("rb") as fh:
        for raw in fh:
            line_no += 1
            try:
                line = raw.decode("utf-8-sig" if line_no == 1 else "utf-8")
            except UnicodeDecodeError as exc:
                raise KeypointFormatError(
                    f"not UTF-8 text (byte {raw[exc.start]:#04x} at column {exc.start + 1}): "
                    "JSON lines are UTF-8",
                    path=path,
                    frame=index,
                    line=line_no,
                ) from None
            if not line.strip():
                continue
            obj = parse_json(line.rstrip("\r\n"), path, index, line_no)
            if not isinstance(obj, dict) or not isinstance(people_of(obj), list):
                raise KeypointFormatError(
                    "each line must be an object with a 'people' (or 'instances') list",
                    path=path,
                    frame=index,
                    line=line_no,
                )
            if index == 0 and rate is None and "fps" in obj:
                rate = obj["fps"]
                if not plausible_fps(rate):
                    raise KeypointFormatError(
                        f"'fps' must be a camera frame rate, {FPS_RANGE}, got {rate!r}",
                        path=path,
                        frame=0,
                        line=line_no,
                    )
            at, first = _position(obj, first, index, 30.0 if rate is None else float(rate))
            if at is not None and first is not None:
                if at < index:
                    raise KeypointFormatError(
                        f"its {first[1]} puts it at frame {at}, not after the line before "
                        f"(frame {index - 1}): lines must come in time order",
                        path=path,
                        frame=index,
                        line=line_no,
                    )
                if at - index > MAX_GAP_FRAMES:
                    raise KeypointFormatError(
                        f"its {first[1]} skips {at - index} frames after frame {index - 1}; "
                        f"more than {MAX_GAP_FRAMES} is no gap in one recording",
                        path=path,
                        frame=index,
                        line=line_no,
                    )
                frames.add_unseen(at - index)  # frames the estimator wrote no line for
                index = at
            people = []
            for k, person in enumerate(people_of(obj)):
                try:
                    people.append(parse_coco_person(person, min_confidence))
                except CocoPersonError as exc:
                    raise KeypointFormatError(
                        f"person {k}: {exc}", path=path, frame=index, line=line_no
                    ) from None
            frames.add(people)
            index += 1
    if index == 0:
        raise KeypointFormatError("no frames (the file is empty)", path=path)
    return frames.sequence(float(rate if rate is not None else 30.0), source=str(path))


def _number(value: Any) -> float | None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    return float(value) if ok and np.isfinite(value) else None


def _position(
    obj: dict[str, Any], first: tuple[float, str] | None, index: int, rate: float
) -> tuple[int | None, tuple[float, str] | None]:
    """Where a line's ``frame`` (else ``t`` at ``rate``) puts it, counted from the first
    line's (None where the line has neither, or the first line had neither); and the first
    line's value and which field it was."""
    frame, t = _number(obj.get("frame")), _number(obj.get("t"))
    if first is None:
        if index > 0:  # the first line carried neither: lines are frames
            return None, None
        if frame is not None:
            return 0, (frame, "frame")
        if t is not None:
            return 0, (t, "t")
        return None, None
    origin, field = first
    if field == "frame" and frame is not None:
        return round(frame - origin), first
    if field == "t" and t is not None:
        return round((t - origin) * rate), first
    return None, first
