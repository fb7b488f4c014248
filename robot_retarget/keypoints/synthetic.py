"""Canonical 3D motion seen by a virtual camera as a pose estimator would report it.

Used to train the keypoint model (random cameras), to evaluate it (held-out cameras) and by the
demo's 2D variant. :class:`EstimatorNoise` imitates what OpenPose / RTMPose-class estimators do
on real video: pixel jitter proportional to the person's size in the image (larger at wrists
and ankles), points dropped at random and in bursts (occlusion), face points lost when the head
turns away, and a confidence per point — low where a point was dropped, so the confidence
threshold marks it missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import FACE_KEYPOINTS, NUM_KEYPOINTS, Coco
from robot_retarget.keypoints.sequence import DEFAULT_MIN_CONFIDENCE
from robot_retarget.keypoints.virtual_camera import VirtualCamera, facing_away, keypoints_3d
from robot_retarget.skeleton.canonical import Joint

_EXTREMITIES = (Coco.left_wrist, Coco.right_wrist, Coco.left_ankle, Coco.right_ankle)


@dataclass(frozen=True)
class CameraRange:
    """Where random virtual cameras are drawn from (degrees, metres, pixels)."""

    elevation_deg: tuple[float, float] = (-10.0, 45.0)
    distance_m: tuple[float, float] = (2.5, 8.0)
    focal_px: tuple[float, float] = (600.0, 1600.0)

    def sample(self, rng: np.random.Generator) -> VirtualCamera:
        return VirtualCamera(
            azimuth_rad=float(rng.uniform(0.0, 2.0 * math.pi)),
            elevation_rad=math.radians(float(rng.uniform(*self.elevation_deg))),
            distance_m=float(rng.uniform(*self.distance_m)),
            focal_px=float(rng.uniform(*self.focal_px)),
        )


@dataclass(frozen=True)
class EstimatorNoise:
    """Estimator-like corruption (see the module docstring). ``jitter`` is the pixel noise's
    standard deviation as a fraction of the person's height in the image."""

    jitter: tuple[float, float] = (0.003, 0.015)
    extremity_factor: float = 1.5
    dropout: tuple[float, float] = (0.0, 0.08)
    burst_probability: float = 0.3
    burst_frames: tuple[int, int] = (5, 30)
    face_hidden_probability: float = 0.8


CLEAN = EstimatorNoise(jitter=(0.0, 0.0), dropout=(0.0, 0.0), burst_probability=0.0,
                       face_hidden_probability=0.0)  # fmt: skip


def render_keypoints(
    positions: FloatArray,
    global_quats: FloatArray,
    height_m: float,
    camera: VirtualCamera,
    rng: np.random.Generator,
    noise: EstimatorNoise = EstimatorNoise(),
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """One performer's frames (T, 22, 3) / (T, 22, 4), Y up → pixels (T, 17, 2), confidence
    (T, 17) and visibility (T, 17) (confidence ≥ the default threshold; NaN pixels elsewhere)."""
    pos = np.asarray(positions, dtype=np.float64)
    t = pos.shape[0]
    target = pos[:, Joint.Hips].mean(axis=0)
    points = keypoints_3d(pos, global_quats, height_m)
    px, depth = camera.project(points, target)
    person_px = camera.focal_px * height_m / max(camera.distance_m, 1e-3)
    sigma = rng.uniform(*noise.jitter) * person_px
    scale = np.ones(NUM_KEYPOINTS)
    scale[list(_EXTREMITIES)] = noise.extremity_factor
    px = px + rng.normal(0.0, 1.0, px.shape) * sigma * scale[None, :, None]
    dropped = rng.random((t, NUM_KEYPOINTS)) < rng.uniform(*noise.dropout)
    if rng.random() < noise.burst_probability:
        k = int(rng.integers(NUM_KEYPOINTS))
        length = int(rng.integers(noise.burst_frames[0], noise.burst_frames[1] + 1))
        start = int(rng.integers(0, max(t - length, 0) + 1))
        dropped[start : start + length, k] = True
    centre, _ = camera.pose(target)
    away = facing_away(global_quats, centre, pos[:, Joint.Head])
    hide_face = away & (rng.random(t) < noise.face_hidden_probability)
    dropped[np.ix_(np.flatnonzero(hide_face), np.array(FACE_KEYPOINTS))] = True
    dropped |= depth <= 0.05  # behind the camera
    confidence = np.where(
        dropped,
        rng.uniform(0.0, 0.9 * DEFAULT_MIN_CONFIDENCE, (t, NUM_KEYPOINTS)),
        rng.uniform(0.5, 1.0, (t, NUM_KEYPOINTS)),
    )
    valid = ~dropped
    px[dropped] = np.nan
    return px, confidence, valid
