"""Virtual pinhole cameras around a performer, and canonical motion → COCO-17 pixels.

A camera sits at ``distance_m`` from a look-at point (the performer's mean hip position), at
``azimuth_rad`` about the vertical (0: on the +Z side, where a performer in the canonical rest
pose faces) and ``elevation_rad`` above the horizontal, looking at the point with the image's
y axis down. The keypoint model's output frame is the world turned so that this camera's
azimuth is 0 (:func:`heading_quat`): from 2D alone the performer's heading is known relative to
the camera, not to the room.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.coco17 import BODY_JOINTS, FACE_OFFSETS_M, NUM_KEYPOINTS
from robot_retarget.skeleton.canonical import Joint

_REFERENCE_HEIGHT_M = 1.7
_BODY_K = np.array(list(BODY_JOINTS), dtype=np.int64)
_BODY_J = np.array(list(BODY_JOINTS.values()), dtype=np.int64)
_FACE_K = np.array(list(FACE_OFFSETS_M), dtype=np.int64)
_FACE_OFFSETS = np.array(list(FACE_OFFSETS_M.values()), dtype=np.float64)


@dataclass(frozen=True)
class VirtualCamera:
    """A static pinhole camera (see the module docstring); focal length and image in pixels."""

    azimuth_rad: float
    elevation_rad: float
    distance_m: float
    focal_px: float
    width_px: int = 1280
    height_px: int = 720

    @property
    def image_size(self) -> tuple[float, float]:
        """(width, height) in pixels, as a keypoint sequence or packet carries it."""
        return (float(self.width_px), float(self.height_px))

    def pose(self, target: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Camera centre (3,) and world→camera rotation (3, 3) (rows: right, down, forward)."""
        a, e = self.azimuth_rad, self.elevation_rad
        direction = np.array([math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)])
        centre = np.asarray(target, dtype=np.float64) + self.distance_m * direction
        forward = -direction
        right = np.cross(forward, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return centre, np.stack([right, -up, forward])

    def project(self, points: FloatArray, target: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World points (..., 3) → pixels (..., 2) and depth (...,) metres along the view."""
        centre, rot = self.pose(target)
        cam = (np.asarray(points, dtype=np.float64) - centre) @ rot.T
        depth = cam[..., 2]
        safe = np.maximum(depth, 1e-3)
        px = np.empty((*cam.shape[:-1], 2))
        px[..., 0] = self.focal_px * cam[..., 0] / safe + 0.5 * self.width_px
        px[..., 1] = self.focal_px * cam[..., 1] / safe + 0.5 * self.height_px
        return px, depth


def heading_quat(azimuth_rad: float | FloatArray) -> FloatArray:
    """The rotation about +Y (w-x-y-z) taking the world into the camera's heading frame."""
    return quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), -np.asarray(azimuth_rad))


def keypoints_3d(positions: FloatArray, global_quats: FloatArray, height_m: float) -> FloatArray:
    """COCO-17 points in the world (..., 17, 3) from canonical joint positions (..., 22, 3) and
    global rotations (..., 22, 4): body points at their joints, face points on the head."""
    pos = np.asarray(positions, dtype=np.float64)
    out = np.empty((*pos.shape[:-2], NUM_KEYPOINTS, 3))
    out[..., _BODY_K, :] = pos[..., _BODY_J, :]
    head_q = np.asarray(global_quats, dtype=np.float64)[..., Joint.Head, None, :]
    scale = height_m / _REFERENCE_HEIGHT_M
    out[..., _FACE_K, :] = pos[..., Joint.Head, None, :] + quat.rotate(
        head_q, _FACE_OFFSETS * scale
    )
    return out


def facing_away(
    global_quats: FloatArray, camera_centre: FloatArray, head_pos: FloatArray
) -> BoolArray:
    """(...,) True where the head faces away from the camera (its face points are hidden)."""
    forward = quat.rotate(np.asarray(global_quats)[..., Joint.Head, :], np.array([0.0, 0.0, 1.0]))
    to_camera = np.asarray(camera_centre) - np.asarray(head_pos)
    away: BoolArray = np.einsum("...i,...i->...", forward, to_camera) < 0.0
    return away
