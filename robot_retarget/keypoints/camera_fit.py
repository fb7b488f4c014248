"""The camera a keypoint sequence came from, fitted to the keypoint model's answer
(robot_retarget.keypoints.reprojection turns the answer's bones into the planes this camera
puts them in; robot_retarget.keypoints.online_reprojection fits it frame by frame).

The camera's elevation is the candidate (−20…60°, 1° steps) under which the lifted upper arms,
thighs, shoulder and hip lines and torso sides point in the image where the keypoints' do; its
focal length comes from the image scale. Two things one image sequence cannot tell are assumed:
the principal point is the performer's median hip centre in the image (the camera points at
the performer), and the camera stands :data:`ASSUMED_DISTANCE_HEIGHTS` body heights away
(about 5.5 m from a 1.7 m adult). The distance only sets how far the rays spread across the
body: the README gives the error for cameras at 2.5 m and 8 m. The frame is the lifted
motion's heading frame: the camera sits on its +Z side, looking back at the performer.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.keypoints.coco17 import BODY_JOINTS, LIMB_BONES, Coco
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import HumanMotion, skeleton_height
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.skeleton import Skeleton

ASSUMED_DISTANCE_HEIGHTS = 3.25
ELEVATIONS_DEG = np.arange(-20.0, 60.5, 1.0)  # candidates: training draws −10…45°

_BODY_K = np.array(list(BODY_JOINTS), dtype=np.int64)
_BODY_J = np.array(list(BODY_JOINTS.values()), dtype=np.int64)

# What fits the camera: the upper arms and thighs, the shoulder and hip lines and the torso's
# sides (not the forearms and shins: wrists and ankles are the noisiest keypoints; on subjects
# 02, 05 and 13 leaving them out took the lifted performer from 6.18° to 6.16°, 6.07° → 6.04°
# with the turned pose smoothed).
FIT_SEGMENTS = [(b[0], b[1]) for b in LIMB_BONES[::2]] + [
    (Joint.LeftArm, Joint.RightArm), (Joint.LeftUpLeg, Joint.RightUpLeg),
    (Joint.LeftUpLeg, Joint.LeftArm), (Joint.RightUpLeg, Joint.RightArm),
]  # fmt: skip
FIT_KEYPOINTS = [(b[2], b[3]) for b in LIMB_BONES[::2]] + [
    (Coco.left_shoulder, Coco.right_shoulder), (Coco.left_hip, Coco.right_hip),
    (Coco.left_hip, Coco.left_shoulder), (Coco.right_hip, Coco.right_shoulder),
]  # fmt: skip
_FIT_STARTS, _FIT_ENDS = (np.array(c, dtype=np.int64) for c in zip(*FIT_SEGMENTS, strict=True))
_FIT_KEY_STARTS, _FIT_KEY_ENDS = (
    np.array(c, dtype=np.int64) for c in zip(*FIT_KEYPOINTS, strict=True)
)
_COST_CHUNK = 32


@dataclass(frozen=True)
class CameraEstimate:
    """The camera a keypoint sequence is taken to come from, in the lifted motion's heading
    frame (it sits on the +Z side, looking back at the performer)."""

    elevation_rad: float
    focal_px: float
    principal_px: FloatArray  # (2,)
    distance_m: float

    def rotation(self) -> FloatArray:
        """Heading frame → camera (rows: right, down, forward)."""
        return _rotation(self.elevation_rad)

    def rays(self, xy: FloatArray) -> FloatArray:
        """Pixels (..., 2) → viewing rays (..., 3) in camera coordinates (not unit)."""
        p = np.asarray(xy, dtype=np.float64) - self.principal_px
        return np.concatenate([p, np.full((*p.shape[:-1], 1), self.focal_px)], axis=-1)


@functools.lru_cache(maxsize=256)  # the live step asks every frame
def _rotation(elevation_rad: float) -> FloatArray:
    rot = VirtualCamera(0.0, elevation_rad, 1.0, 1.0).pose(np.zeros(3))[1]
    rot.setflags(write=False)
    return rot


def candidate_rotations(elevations_deg: FloatArray = ELEVATIONS_DEG) -> FloatArray:
    """(E, 3, 3) heading frame → camera rotations of the candidate elevations."""
    return np.stack([_rotation(math.radians(e)) for e in elevations_deg])


def _project(rel: FloatArray, rots: FloatArray, distance: float) -> FloatArray:
    """Points (T, N, 3) relative to the hips, heading frame → image (E, T, N, 2) through each of
    the rotations (E, 3, 3) at unit focal length over ``distance`` (x right, y down)."""
    cam = rel[None] @ np.swapaxes(rots, -1, -2)[:, None]
    return np.asarray(cam[..., :2] / (1.0 + cam[..., 2:] / distance), dtype=np.float64)


def direction_costs(
    rel: FloatArray, xy: FloatArray, rots: FloatArray, distance: float
) -> FloatArray:
    """(E,) how far the image directions of the fitted segments of ``rel`` (T, 22, 3, joint
    positions relative to the hips) under each rotation (E, 3, 3) are from the keypoints'
    ``xy`` (T, 17, 2, NaN where missing): Σ over frames and segments of the keypoints' segment
    length × (1 − cos of the angle between the two directions)."""
    seen = xy[:, _FIT_KEY_ENDS] - xy[:, _FIT_KEY_STARTS]  # (T, S, 2)
    ok: BoolArray = np.asarray(np.isfinite(seen).all(axis=-1))
    seen = np.where(ok[..., None], seen, 0.0)
    weight = np.sqrt(np.sum(seen * seen, axis=-1))  # 0 where missing
    seen_dir = seen / np.maximum(weight, 1e-9)[..., None]
    proj = _project(rel, rots, distance)
    vec = proj[:, :, _FIT_ENDS] - proj[:, :, _FIT_STARTS]  # (E, T, S, 2)
    norm = np.sqrt(np.sum(vec * vec, axis=-1))
    cos = np.sum(vec * seen_dir, axis=-1) / np.maximum(norm, 1e-12)
    return np.asarray(np.sum(weight * (1.0 - cos), axis=(1, 2)), dtype=np.float64)


def image_scales(rel: FloatArray, xy: FloatArray, rot: FloatArray, distance: float) -> FloatArray:
    """Per-frame image scale (pixels per metre at the hips' depth; least squares over the body
    points, offsets free) of the frames with three or more body points seen
    (:func:`scaled_frames`)."""
    obs = xy[:, _BODY_K]
    w = np.asarray(np.isfinite(obs).all(axis=-1), dtype=np.float64)
    frames = scaled_frames(xy)
    proj = _project(rel[frames][:, _BODY_J], rot[None], distance)[0]
    obs, w = np.nan_to_num(obs[frames]), w[frames]
    n = np.maximum(w.sum(axis=1), 1.0)[:, None, None]
    obs_c = obs - (obs * w[..., None]).sum(axis=1, keepdims=True) / n
    proj_c = proj - (proj * w[..., None]).sum(axis=1, keepdims=True) / n
    num = ((proj_c * obs_c).sum(-1) * w).sum(1)
    return np.asarray(num / np.maximum(((proj_c * proj_c).sum(-1) * w).sum(1), 1e-12))


def scaled_frames(xy: FloatArray) -> BoolArray:
    """(T,) the frames of keypoints ``xy`` (T, 17, 2) with an image scale: three or more body
    points seen (a scale and an offset need a few points)."""
    enough: BoolArray = np.isfinite(xy[:, _BODY_K]).all(axis=-1).sum(axis=1) >= 3
    return enough


def frame_scales(rel: FloatArray, xy: FloatArray, camera: CameraEstimate) -> FloatArray:
    """(T,) :func:`image_scales` under ``camera`` of every frame, NaN where there is none."""
    out = np.full(len(rel), np.nan)
    out[scaled_frames(xy)] = image_scales(rel, xy, camera.rotation(), camera.distance_m)
    return out


def camera_distance(skeleton: Skeleton) -> float:
    """The assumed camera distance (metres) for a performer lifted onto ``skeleton``."""
    return ASSUMED_DISTANCE_HEIGHTS * skeleton_height(skeleton)


def estimate_camera(motion: HumanMotion, xy: FloatArray) -> CameraEstimate | None:
    """The camera (module docstring) that best reprojects ``motion`` (the keypoint model's
    answer, heading frame) onto ``xy`` (T, 17, 2, NaN where missing); None where the keypoints
    cannot tell (no segment seen at both ends, no frame with three body points, no positive
    image scale).

    The elevation is the one under which the lifted bones' image directions best match the
    keypoints' (:func:`direction_costs`). Directions, not positions: the performer's
    proportions are not the reference skeleton's, and a fit of positions tilts the camera to
    make up the difference (on subjects 02 and 13 its elevation was 5–17° off at 30°, the
    directions' 1–10°). The focal length then comes from the median image scale."""
    pos = motion.positions()
    return fit_camera(np.asarray(pos - pos[:, :1]), motion.skeleton, xy)


def fit_camera(rel: FloatArray, skeleton: Skeleton, xy: FloatArray) -> CameraEstimate | None:
    """:func:`estimate_camera` from the joint positions ``rel`` (T, 22, 3) relative to the hips
    of a pose on ``skeleton`` (for a caller that has them already)."""
    distance = camera_distance(skeleton)
    obs = np.asarray(xy, dtype=np.float64)
    seen = np.isfinite(obs[:, _FIT_KEY_ENDS] - obs[:, _FIT_KEY_STARTS]).all(axis=-1)
    if not seen.any():
        return None
    rots = candidate_rotations()
    costs = np.zeros(len(rots))
    for t in range(0, len(rel), _COST_CHUNK):  # bounded memory on long clips
        costs += direction_costs(rel[t : t + _COST_CHUNK], obs[t : t + _COST_CHUNK], rots, distance)
    best = int(np.argmin(costs))
    scales = image_scales(rel, obs, rots[best], distance)
    focal = float(np.median(scales)) * distance if len(scales) else math.nan
    if not (math.isfinite(focal) and focal > 0.0):
        return None
    hips = 0.5 * (obs[:, Coco.left_hip] + obs[:, Coco.right_hip])
    hips_seen = np.isfinite(hips).all(axis=-1)
    principal = np.median(
        hips[hips_seen] if hips_seen.any() else obs[np.isfinite(obs).all(-1)], axis=0
    )
    return CameraEstimate(math.radians(ELEVATIONS_DEG[best]), focal, principal, distance)
