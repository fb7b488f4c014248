"""MediaPipe Pose landmarks as JSON: 33 normalised landmarks per person per frame.

MediaPipe's PoseLandmarker (Tasks API) returns, per image, ``pose_landmarks``: one list of 33
``NormalizedLandmark`` (x, y normalised by the image width and height, z, ``visibility``,
``presence``) per detected person, in the order of its pose model card (0 nose, 2 left eye,
5 right eye, 7 left ear, 8 right ear, 11/12 shoulders, 13/14 elbows, 15/16 wrists, 23/24 hips,
25/26 knees, 27/28 ankles; the rest — eye corners, mouth, hands, heels, toes — are not used).
MediaPipe has no file format of its own; this reader takes its result written as JSON:

    {"image_width": 1280, "image_height": 720, "fps": 30,
     "frames": [{"pose_landmarks": [[{"x": 0.51, "y": 0.32, "z": -0.2, "visibility": 0.99,
                                      "presence": 0.99}, ... 33], ... per person]}, ...]}

(the legacy Solutions API's single person, ``"pose_landmarks": [{...} × 33]``, is accepted
too). A point's confidence is its ``visibility`` (times ``presence`` when given). Pixel
coordinates are x · image_width, y · image_height: the image size is required, because
normalised x and y have different units.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS, Coco
from robot_retarget.keypoints.sequence import DEFAULT_MIN_CONFIDENCE, KeypointSequence
from robot_retarget.motion.frame_rate import FPS_RANGE, plausible_fps
from robot_retarget.sources.keypoints.errors import KeypointFormatError, json_fault, read_text
from robot_retarget.sources.keypoints.frames import Person, PersonFrames

NUM_LANDMARKS = 33
_MEDIAPIPE = {
    "nose": 0, "left_eye": 2, "right_eye": 5, "left_ear": 7, "right_ear": 8,
    "left_shoulder": 11, "right_shoulder": 12, "left_elbow": 13, "right_elbow": 14,
    "left_wrist": 15, "right_wrist": 16, "left_hip": 23, "right_hip": 24, "left_knee": 25,
    "right_knee": 26, "left_ankle": 27, "right_ankle": 28,
}  # fmt: skip
_INDEX = np.array([_MEDIAPIPE[Coco(k).name] for k in range(NUM_KEYPOINTS)], dtype=np.int64)


def _size(doc: dict[str, Any], key: str, path: Path) -> float:
    value = doc.get(key)
    size = math.nan
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        try:
            size = float(value)
        except OverflowError:  # an integer too large for a float
            size = math.inf
    if not 0 < size < math.inf:
        raise KeypointFormatError(
            f"'{key}' must be the image size in pixels (a positive number), got "
            f"{repr(value)[:40]}: MediaPipe's coordinates are normalised by it",
            path=path,
        )
    return size


def _person(landmarks: object, w: float, h: float, path: Path, frame: int, k: int,
            min_confidence: float) -> Person:  # fmt: skip
    if not isinstance(landmarks, list) or len(landmarks) != NUM_LANDMARKS:
        n = len(landmarks) if isinstance(landmarks, list) else type(landmarks).__name__
        raise KeypointFormatError(
            f"person {k}: expected {NUM_LANDMARKS} landmarks, got {n}", path=path, frame=frame
        )
    rows = np.empty((NUM_LANDMARKS, 3))
    for i, lm in enumerate(landmarks):
        try:
            x, y = float(lm["x"]), float(lm["y"])
            c = float(lm.get("visibility", 1.0)) * float(lm.get("presence", 1.0))
        except (TypeError, KeyError, ValueError, AttributeError, OverflowError):
            raise KeypointFormatError(
                f"person {k}, landmark {i}: needs numeric 'x' and 'y' ('visibility' and "
                f"'presence' numbers too where given), got {lm!r}"[:300],
                path=path,
                frame=frame,
            ) from None
        rows[i] = (x * w, y * h, c)
    sel = rows[_INDEX]
    valid = np.isfinite(sel).all(axis=1) & (sel[:, 2] >= min_confidence)
    return sel[:, :2].copy(), np.nan_to_num(sel[:, 2]), valid


def read_mediapipe_json(
    path: Path, *, fps: float | None = None, min_confidence: float = DEFAULT_MIN_CONFIDENCE
) -> KeypointSequence:
    """A MediaPipe landmark JSON (see the module docstring) → the followed person's sequence."""
    doc, fault = json_fault(read_text(path))
    if fault is not None:
        raise KeypointFormatError(
            f"{fault}; a .json is read as MediaPipe landmarks, and COCO-17 JSON lines (one "
            "frame per line) are read from a .jsonl file",
            path=path,
        )
    if not (isinstance(doc, dict) and "frames" in doc):
        raise KeypointFormatError(
            "expected MediaPipe landmarks: an object with 'image_width', 'image_height' and "
            "'frames' (a .json is read as MediaPipe's; see the README's \"Video input\")",
            path=path,
        )
    w, h = _size(doc, "image_width", path), _size(doc, "image_height", path)
    rate = fps if fps is not None else doc.get("fps", 30.0)
    if not plausible_fps(rate):
        raise KeypointFormatError(
            f"'fps' must be a camera frame rate, {FPS_RANGE}, got {rate!r}", path=path
        )
    frames_doc = doc["frames"]
    if not isinstance(frames_doc, list) or not frames_doc:
        raise KeypointFormatError("'frames' must be a non-empty list", path=path)
    frames = PersonFrames()
    for i, frame in enumerate(frames_doc):
        if not isinstance(frame, dict) or not isinstance(frame.get("pose_landmarks"), list):
            raise KeypointFormatError("needs a 'pose_landmarks' list", path=path, frame=i)
        people = frame["pose_landmarks"]
        if people and isinstance(people[0], dict):  # Solutions API: one person, no outer list
            people = [people]
        frames.add([_person(p, w, h, path, i, k, min_confidence) for k, p in enumerate(people)])
    return frames.sequence(float(rate), source=str(path), image_size=(w, h))
