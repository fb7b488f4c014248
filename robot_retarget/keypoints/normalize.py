"""Per-frame keypoint features for the keypoint model: centred, scaled, masked.

Pixels say nothing about metres, so each frame is expressed relative to the performer: the
centre is the mid-hip point (held from the last frame where both hips were seen), the scale a
running average of the torso length in pixels (shoulder centre to hip centre, whenever all four
points are seen; bounding-box height / 3 until then). Both are causal (this and earlier frames
only), so the live step and whole clips see the same numbers. Features per keypoint: x, y
(y up) in torso lengths, clipped to ±``CLIP``, and a 1/0 visibility flag; invisible points are
0, 0, 0 — the model is told they are missing, nothing is filled in.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import NUM_KEYPOINTS, Coco

FEATURES_PER_FRAME = NUM_KEYPOINTS * 3
SCALE_RATE = 0.1  # weight of a new torso-length measurement in the running average
CLIP = 4.0
_DEFAULT_SCALE_PX = 100.0
_HIPS = (int(Coco.left_hip), int(Coco.right_hip))
_SHOULDERS = (int(Coco.left_shoulder), int(Coco.right_shoulder))


class KeypointNormalizer:
    """Features of a batch of streams, one frame at a time (see the module docstring).

    ``step(xy (B, 17, 2), valid (B, 17)) → (B, 51)``; :func:`normalize_sequences` runs it over
    whole windows.
    """

    def __init__(self, batch: int = 1) -> None:
        self.batch = batch
        self.reset()

    def reset(self) -> None:
        self._centre = np.full((self.batch, 2), np.nan)
        self._scale = np.full(self.batch, np.nan)

    def step(self, xy: FloatArray, valid: BoolArray) -> FloatArray:
        v = np.asarray(valid, dtype=bool)
        p = np.where(v[..., None], np.asarray(xy, dtype=np.float64), 0.0)
        hips_seen = v[:, _HIPS[0]] & v[:, _HIPS[1]]
        shoulders_seen = v[:, _SHOULDERS[0]] & v[:, _SHOULDERS[1]]
        hip_mid = 0.5 * (p[:, _HIPS[0]] + p[:, _HIPS[1]])
        shoulder_mid = 0.5 * (p[:, _SHOULDERS[0]] + p[:, _SHOULDERS[1]])
        count = v.sum(axis=1)
        any_seen = count > 0
        mean_seen = p.sum(axis=1) / np.maximum(count, 1)[:, None]
        # Centre: mid-hip when seen, else the last centre, else the mean of what is seen.
        centre = np.where(hips_seen[:, None], hip_mid, self._centre)
        first = np.isnan(centre[:, 0]) & any_seen
        centre[first] = mean_seen[first]
        self._centre = centre
        # Scale: running torso length; the bounding box until a torso was seen.
        torso = np.linalg.norm(shoulder_mid - hip_mid, axis=1)
        measured = hips_seen & shoulders_seen & (torso > 1.0)
        y = p[..., 1]
        box = (np.where(v, y, -np.inf).max(axis=1) - np.where(v, y, np.inf).min(axis=1)) / 3.0
        box = np.where(any_seen & (box > 1.0), box, _DEFAULT_SCALE_PX)
        scale = self._scale
        fresh = np.isnan(scale)
        updated = np.where(fresh, torso, scale + SCALE_RATE * (torso - scale))
        scale = np.where(measured, updated, np.where(fresh, box, scale))
        # A bounding-box guess is replaced by the first real torso measurement.
        self._scale = np.where(measured | ~fresh, scale, np.nan)
        safe_centre = np.where(np.isnan(centre), 0.0, centre)
        rel = (p - safe_centre[:, None, :]) / scale[:, None, None]
        rel[..., 1] *= -1.0
        rel = np.clip(rel, -CLIP, CLIP) * v[..., None]
        out = np.concatenate([rel, v[..., None].astype(np.float64)], axis=-1)
        return out.reshape(self.batch, FEATURES_PER_FRAME)


def normalize_sequences(xy: FloatArray, valid: BoolArray) -> FloatArray:
    """Features (B, T, 51) of windows ``xy`` (B, T, 17, 2) with ``valid`` (B, T, 17)."""
    b, t = valid.shape[:2]
    norm = KeypointNormalizer(b)
    out = np.empty((b, t, FEATURES_PER_FRAME))
    for i in range(t):
        out[:, i] = norm.step(xy[:, i], valid[:, i])
    return out
