"""2D keypoint inputs: files from pose estimators, and live COCO-17 over UDP.

- OpenPose JSON folder (BODY_25 or COCO-18): :mod:`.openpose`
- MediaPipe Pose landmark JSON (33 points): :mod:`.mediapipe`
- COCO-17 JSON lines (RTMPose / YOLO-pose / ViTPose): :mod:`.coco_jsonl`
- live COCO-17 over UDP: :mod:`.udp_keypoints`

Every reader maps its layout onto COCO-17, marks undetected or low-confidence points missing
(:class:`robot_retarget.keypoints.sequence.KeypointSequence`) and follows one person by the
rule of :mod:`.person_choice`. :func:`load_keypoints` picks the reader from the path.
"""

from __future__ import annotations

from pathlib import Path

from robot_retarget.keypoints.sequence import DEFAULT_MIN_CONFIDENCE, KeypointSequence
from robot_retarget.sources.keypoints.coco_jsonl import read_coco_jsonl
from robot_retarget.sources.keypoints.errors import KeypointFormatError
from robot_retarget.sources.keypoints.mediapipe import read_mediapipe_json
from robot_retarget.sources.keypoints.openpose import is_openpose_folder, read_openpose_folder

__all__ = ["KeypointFormatError", "is_keypoint_input", "load_keypoints"]

KEYPOINT_FORMS = (
    "an OpenPose JSON folder, a MediaPipe landmark .json, or COCO-17 .jsonl (JSON lines)"
)


def is_keypoint_input(path: Path) -> bool:
    """True for the keypoint forms above (a folder of BVH clips is not one)."""
    if path.is_dir():
        return is_openpose_folder(path)
    # A .json is read as MediaPipe's (the one JSON form; motion files are BVH), so that a
    # wrong one gets the reader's error, not "unsupported motion file type".
    return path.suffix.lower() in (".jsonl", ".json")


def load_keypoints(
    path: Path, *, fps: float | None = None, min_confidence: float = DEFAULT_MIN_CONFIDENCE
) -> KeypointSequence:
    """Read any keypoint form; raises KeypointFormatError naming the file (and frame)."""
    if path.is_dir():
        return read_openpose_folder(path, fps=fps or 30.0, min_confidence=min_confidence)
    if path.suffix.lower() == ".jsonl":
        return read_coco_jsonl(path, fps=fps, min_confidence=min_confidence)
    if path.suffix.lower() == ".json":
        return read_mediapipe_json(path, fps=fps, min_confidence=min_confidence)
    raise KeypointFormatError(f"not a keypoint input; give {KEYPOINT_FORMS}", path=path)
