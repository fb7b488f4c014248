"""OpenPose JSON output: a folder of one file per frame (``--write_json``).

Each file (OpenPose 1.x, doc/02_output.md): ``{"version": 1.3, "people": [{"person_id": [-1],
"pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...], ...}]}``, pixel coordinates, a missing
point written as 0, 0, 0. The body model follows from the length: 25 × 3 values = BODY_25
(OpenPose's default), 18 × 3 = COCO-18 (``--model_pose COCO``). Files are taken in the order
of the frame numbers in their names (OpenPose names them ``<video>_<12-digit
frame>_keypoints.json``); a number skipped is a frame in which nobody was seen, so the frames
after it keep their time. Names without numbers are taken in name order. Both layouts are
mapped onto COCO-17 (their extra points — neck, mid-hip, feet — are not used).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS, Coco
from robot_retarget.keypoints.sequence import DEFAULT_MIN_CONFIDENCE, KeypointSequence
from robot_retarget.sources.keypoints.errors import KeypointFormatError, parse_json, read_text
from robot_retarget.sources.keypoints.frames import MAX_GAP_FRAMES, PersonFrames

_BODY_25 = {
    "nose": 0, "right_shoulder": 2, "right_elbow": 3, "right_wrist": 4, "left_shoulder": 5,
    "left_elbow": 6, "left_wrist": 7, "right_hip": 9, "right_knee": 10, "right_ankle": 11,
    "left_hip": 12, "left_knee": 13, "left_ankle": 14, "right_eye": 15, "left_eye": 16,
    "right_ear": 17, "left_ear": 18,
}  # fmt: skip
_COCO_18 = {
    "nose": 0, "right_shoulder": 2, "right_elbow": 3, "right_wrist": 4, "left_shoulder": 5,
    "left_elbow": 6, "left_wrist": 7, "right_hip": 8, "right_knee": 9, "right_ankle": 10,
    "left_hip": 11, "left_knee": 12, "left_ankle": 13, "right_eye": 14, "left_eye": 15,
    "right_ear": 16, "left_ear": 17,
}  # fmt: skip
LAYOUTS: dict[int, tuple[str, dict[str, int]]] = {
    25: ("BODY_25", _BODY_25),
    18: ("COCO-18", _COCO_18),
}


def _to_coco(layout: dict[str, int]) -> np.ndarray:
    return np.array([layout[Coco(k).name] for k in range(NUM_KEYPOINTS)], dtype=np.int64)


_INDEX = {n: _to_coco(layout) for n, (_name, layout) in LAYOUTS.items()}


def openpose_files(folder: Path) -> list[Path]:
    """The folder's ``*.json`` files in frame order: by the number in their names where every
    name has one (OpenPose's ``<video>_<frame>_keypoints.json``; unpadded numbers too), else
    in name order."""
    return _numbered_files(folder)[0]


def _numbered_files(folder: Path) -> tuple[list[Path], list[int] | None]:
    """The folder's ``*.json`` files in frame order, and their frame numbers (None: in name
    order, :func:`frame_numbers`)."""
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() == ".json")
    numbers = frame_numbers(files)
    if numbers is None:
        return files, None
    ordered = sorted(zip(numbers, files, strict=True))
    return [f for _, f in ordered], [n for n, _ in ordered]


def frame_numbers(files: list[Path]) -> list[int] | None:
    """Each file's frame number (the last run of digits in its name), or None where a name
    has none or two share one: the files are then frames in name order."""
    numbers = []
    for f in files:
        digits = _DIGITS.findall(f.stem)
        if not digits:
            return None
        numbers.append(int(digits[-1]))
    return numbers if len(set(numbers)) == len(numbers) else None


_DIGITS = re.compile(r"\d+")


def is_openpose_folder(folder: Path) -> bool:
    """A folder of OpenPose's frame files: one named ``*_keypoints.json``, or a first JSON file
    with a ``people`` list."""
    if not folder.is_dir():
        return False
    files = openpose_files(folder)
    if not files:
        return False
    if any(f.name.lower().endswith("_keypoints.json") for f in files):
        return True  # OpenPose's names: a broken first file is the reader's to name
    try:
        doc = json.loads(files[0].read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return True  # claimed by its shape; the reader reports the broken file
    return isinstance(doc, dict) and "people" in doc


def parse_openpose_people(
    doc: object, path: Path, frame: int, min_confidence: float
) -> list[tuple[FloatArray, FloatArray, BoolArray]]:
    """One frame document → (xy (17, 2), confidence (17,), valid (17,)) per person."""
    if not isinstance(doc, dict) or not isinstance(doc.get("people"), list):
        raise KeypointFormatError("expected an object with a 'people' list", path=path, frame=frame)
    out = []
    for k, person in enumerate(doc["people"]):
        values = person.get("pose_keypoints_2d") if isinstance(person, dict) else None
        if not isinstance(values, list):
            raise KeypointFormatError(
                f"person {k} has no 'pose_keypoints_2d' list", path=path, frame=frame
            )
        try:
            a = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise KeypointFormatError(
                f"person {k}: 'pose_keypoints_2d' holds non-numbers", path=path, frame=frame
            ) from None
        if a.ndim != 1:
            raise KeypointFormatError(
                f"person {k}: 'pose_keypoints_2d' must be one flat list of x, y, confidence "
                f"values, got a nested list of shape {a.shape}",
                path=path,
                frame=frame,
            )
        if a.size % 3 or a.size // 3 not in LAYOUTS:
            raise KeypointFormatError(
                f"person {k}: 'pose_keypoints_2d' has {a.size} values; expected 75 (BODY_25) "
                "or 54 (COCO-18) x, y, confidence triples",
                path=path,
                frame=frame,
            )
        triples = a.reshape(-1, 3)[_INDEX[a.size // 3]]
        conf = triples[:, 2]
        # OpenPose writes an undetected point as 0, 0, 0.
        valid = np.isfinite(triples).all(axis=1) & (conf >= min_confidence) & (conf > 0.0)
        out.append((triples[:, :2].copy(), np.nan_to_num(conf), valid))
    return out


def read_openpose_folder(
    folder: Path, *, fps: float = 30.0, min_confidence: float = DEFAULT_MIN_CONFIDENCE
) -> KeypointSequence:
    """Every frame file of ``folder``; one person followed (robot_retarget.sources.keypoints.
    person_choice). Raises KeypointFormatError naming the file and its frame index."""
    files, numbers = _numbered_files(folder)
    if not files:
        raise KeypointFormatError("no .json frame files in this folder", path=folder)
    frames = PersonFrames()
    i = 0  # the next frame's position
    for k, path in enumerate(files):
        if numbers is not None and k > 0:
            gap = numbers[k] - numbers[k - 1] - 1
            if gap > MAX_GAP_FRAMES:
                raise KeypointFormatError(
                    f"its name's frame number {numbers[k]} comes {gap} frames after "
                    f"{numbers[k - 1]}; more than {MAX_GAP_FRAMES} is no gap in one recording",
                    path=path,
                    frame=i,
                )
            frames.add_unseen(gap)  # frames OpenPose wrote no file for
            i += gap
        doc = parse_json(read_text(path, i), path, i)
        frames.add(parse_openpose_people(doc, path, i, min_confidence))
        i += 1
    return frames.sequence(fps, source=str(folder))
