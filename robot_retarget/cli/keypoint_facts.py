"""``inspect`` of 2D keypoint input (an OpenPose JSON folder, MediaPipe landmark JSON, COCO-17
JSON lines): what ``convert`` and the keypoint model will get — frames and rate, the image
size, and how much the estimator missed (points below the confidence threshold count as
missing, as everywhere; frames with no point at all hold the last pose in ``convert``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.keypoints.coco17 import COCO17_NAMES
from robot_retarget.sources.keypoints import load_keypoints
from robot_retarget.sources.keypoints.openpose import is_openpose_folder


def is_keypoint_file(path: str) -> bool:
    """An OpenPose folder, COCO-17 .jsonl, or a .json that is not a robot trajectory (those
    carry ``joint_names``): MediaPipe's landmarks."""
    p = Path(path)
    if p.is_dir():
        return is_openpose_folder(p)
    suffix = p.suffix.lower()
    if suffix == ".jsonl":
        return True
    if suffix != ".json":
        return False
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return True  # the keypoint reader names what is wrong with it
    return not (isinstance(doc, dict) and "joint_names" in doc)


def describe_keypoints(path: str) -> dict[str, Any]:
    """Facts about one keypoint input, as JSON-ready values."""
    seq = load_keypoints(Path(path))
    missing = 1.0 - seq.valid.mean(axis=0)  # per keypoint
    worst = np.argsort(-missing)[:3]
    return {
        "file": path,
        "kind": "2D keypoints",
        "frames": seq.num_frames,
        "fps": seq.fps,
        "duration_s": seq.num_frames / seq.fps,
        "image_size": None if seq.image_size is None else list(seq.image_size),
        "missing_share": seq.missing_fraction,
        "frames_without_body": int(np.count_nonzero(~seq.valid.any(axis=1))),
        "most_missed": {COCO17_NAMES[k]: float(missing[k]) for k in worst if missing[k] > 0},
    }


def format_keypoints_text(info: dict[str, Any]) -> str:
    size = info["image_size"]
    missed = ", ".join(f"{name} {share:.0%}" for name, share in info["most_missed"].items())
    return "\n".join(
        [
            f"{info['file']}",
            "  kind:        2D keypoints (mapped to COCO-17)",
            f"  frames:      {info['frames']} at {info['fps']:.6g} fps "
            f"({info['duration_s']:.3f} s)",
            f"  image:       {'unknown size' if size is None else f'{size[0]:g} × {size[1]:g} px'}",
            f"  missing:     {info['missing_share']:.1%} of points"
            + (f" (most: {missed})" if missed else "")
            + f"; {info['frames_without_body']} frame(s) without a body",
        ]
    )
