"""``--image-size WxH``: a camera image's width and height in pixels (``stream``'s keypoints)."""

from __future__ import annotations

import argparse
import re

from robot_retarget.keypoints.sequence import check_image_size

_FORM = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*[xX×]\s*(\d+(?:\.\d*)?)\s*$")


def image_size_argument(text: str) -> tuple[float, float]:
    """``"1280x720"`` → (1280.0, 720.0); argparse's error for anything else."""
    match = _FORM.match(text)
    if match is None:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT in pixels, e.g. 1280x720")
    try:
        return check_image_size((float(match[1]), float(match[2])))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: width and height must both be positive, e.g. 1280x720"
        ) from None
