"""KeypointSequence: 2D keypoints of one person over time, with what is missing marked.

Pixel coordinates (x right, y down, the image's own), a confidence per point as the estimator
gave it, and ``valid``: a point counts only when it was detected with confidence ≥ the
threshold. Invalid points are kept as NaN coordinates so nothing downstream can use them by
accident; the keypoint model sees them as masked, never as guessed positions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS

DEFAULT_MIN_CONFIDENCE = 0.3
"""Below this an estimator's point is treated as missing (OpenPose's own render threshold is
0.05–0.1; RTMPose / ViTPose demos draw from 0.3)."""


@dataclass(frozen=True, eq=False)
class KeypointSequence:
    """``xy`` (T, 17, 2) pixels (NaN where invalid), ``confidence`` (T, 17) in [0, 1],
    ``valid`` (T, 17), at ``fps``; ``source`` names the file or stream it came from;
    ``image_size`` (width, height) in pixels where the input says (its centre is the camera's
    principal point, to the few pixels a lens is off: ``stream``'s image planes use it)."""

    xy: FloatArray = field(repr=False)
    confidence: FloatArray = field(repr=False)
    valid: BoolArray = field(repr=False)
    fps: float
    source: str = ""
    image_size: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        t = self.xy.shape[0]
        if self.xy.shape != (t, NUM_KEYPOINTS, 2) or t == 0:
            raise ValueError(f"xy must have shape (T>0, {NUM_KEYPOINTS}, 2), got {self.xy.shape}")
        if self.confidence.shape != (t, NUM_KEYPOINTS) or self.valid.shape != (t, NUM_KEYPOINTS):
            raise ValueError("confidence and valid must have shape (T, 17)")
        if not self.fps > 0.0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        if self.image_size is not None:
            check_image_size(self.image_size)

    @property
    def num_frames(self) -> int:
        return int(self.xy.shape[0])

    @property
    def missing_fraction(self) -> float:
        """Share of points marked missing (undetected or below the confidence threshold)."""
        return float(1.0 - self.valid.mean())

    @classmethod
    def from_points(
        cls,
        xy: FloatArray,
        confidence: FloatArray,
        fps: float,
        *,
        min_confidence: float = DEFAULT_MIN_CONFIDENCE,
        source: str = "",
        image_size: tuple[float, float] | None = None,
    ) -> KeypointSequence:
        """Mark points with confidence < ``min_confidence`` or non-finite coordinates invalid."""
        xy = np.array(xy, dtype=np.float64)
        conf = np.array(confidence, dtype=np.float64)
        valid = np.isfinite(xy).all(axis=-1) & np.isfinite(conf) & (conf >= min_confidence)
        xy[~valid] = np.nan
        conf = np.where(np.isfinite(conf), conf, 0.0)
        return cls(xy, conf, valid, float(fps), source, image_size)


def check_image_size(size: tuple[float, float]) -> tuple[float, float]:
    """``size`` (width, height) if both are finite and positive; ValueError otherwise."""
    if len(size) != 2 or not all(math.isfinite(v) and v > 0.0 for v in size):
        raise ValueError(f"image size must be two positive pixel counts, got {size}")
    return (float(size[0]), float(size[1]))


def image_centre(size: tuple[float, float] | None) -> FloatArray | None:
    """The centre (2,) of an image of ``size`` (width, height) pixels; None for None."""
    if size is None:
        return None
    return 0.5 * np.asarray(size, dtype=np.float64)
