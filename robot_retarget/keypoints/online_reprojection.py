"""The image's planes for ``stream``: :mod:`robot_retarget.keypoints.reprojection` one camera
frame at a time, the camera (:mod:`robot_retarget.keypoints.camera_fit`) fitted so far.

``convert`` fits the camera on the whole clip and smooths the keypoints with the frames after
each one; a live stream has neither. Here the camera is fitted on the frames so far: the
candidate elevations' direction costs are sums over frames, so they are kept as running sums;
the image scale is a running mean of its logarithm, the principal point a running mean of the
hip centre. Until :data:`MIN_SECONDS` of frames have shown a body the pose passes through as
the model gave it. The keypoints are used as they arrive (no smoothing: it would look ahead or lag).
"""

from __future__ import annotations

import math

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.keypoints.camera_fit import (
    ELEVATIONS_DEG,
    CameraEstimate,
    camera_distance,
    candidate_rotations,
    direction_costs,
    image_scales,
)
from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.keypoints.reprojection import MatrixPose, apply_changes, plane_changes
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton

MIN_SECONDS = 0.5
"""Frames with a body seen for this long before the camera is trusted (15 at 30 fps)."""
CHANGE_RATE = 0.3
"""At 30 fps each frame's turns move the applied ones this share of the way (an exponential
average: the keypoints' frame-to-frame noise is in the turns, the model's error they correct
is not); at other frame rates the share with the same time constant (chosen on subjects 02
and 13: 0.5 / 0.3 / 0.2 / 0.1 gave 6.61° / 6.62° / 6.72° / 6.94°)."""
_RATE_FPS = 30.0


class OnlineReprojection:
    """``step(local (22, 4), xy (17, 2, NaN where missing)) → (22, 4)``: the model's answer
    for one camera frame turned into the image's planes, the camera fitted on the frames so
    far (module docstring). ``reset()`` forgets the camera (a new sender, maybe a new one)."""

    def __init__(self, skeleton: Skeleton | None = None, fps: float = 30.0) -> None:
        if not (math.isfinite(fps) and fps > 0.0):
            raise ValueError(f"fps must be positive, got {fps}")
        self.skeleton = skeleton or default_canonical_skeleton()
        self.min_frames = max(1, round(MIN_SECONDS * fps))
        self.rate = 1.0 - (1.0 - CHANGE_RATE) ** (_RATE_FPS / fps)
        self._rots = candidate_rotations()
        self._distance = camera_distance(self.skeleton)
        self.reset()

    def reset(self) -> None:
        self._costs = np.zeros(len(self._rots))
        self._log_scale = 0.0
        self._scales = 0
        self._hips = np.zeros(2)
        self._hips_seen = 0
        self._changes: FloatArray | None = None

    @property
    def camera(self) -> CameraEstimate | None:
        """The camera fitted so far, or None before :data:`MIN_SECONDS` of frames with a body."""
        if min(self._scales, self._hips_seen) < self.min_frames:
            return None
        best = int(np.argmin(self._costs))
        focal = math.exp(self._log_scale / self._scales) * self._distance
        principal = self._hips / self._hips_seen
        return CameraEstimate(math.radians(ELEVATIONS_DEG[best]), focal, principal, self._distance)

    def step(self, local: FloatArray, xy: FloatArray) -> FloatArray:
        pose = MatrixPose.of(self.skeleton, np.asarray(local, dtype=np.float64)[None])
        obs = np.asarray(xy, dtype=np.float64)[None]
        rel = pose.positions  # the root is at the origin
        self._costs += direction_costs(rel, obs, self._rots, self._distance)
        scale = image_scales(rel, obs, self._rots[int(np.argmin(self._costs))], self._distance)
        if len(scale) and math.isfinite(scale[0]) and scale[0] > 0.0:
            self._log_scale += math.log(scale[0])
            self._scales += 1
        hips = 0.5 * (obs[0, Coco.left_hip] + obs[0, Coco.right_hip])
        if np.isfinite(hips).all():
            self._hips += hips
            self._hips_seen += 1
        camera = self.camera
        if camera is None:
            return pose.local[0]
        changes = plane_changes(pose, obs, camera)[0]
        if self._changes is None:  # the turns fade in from none: no jolt when the camera is set
            self._changes = np.tile([1.0, 0.0, 0.0, 0.0], (len(changes), 1))
        # Both have w > 0: a normalised lerp is a fine average.
        changes = self._changes + self.rate * (changes - self._changes)
        changes /= np.linalg.norm(changes, axis=-1, keepdims=True)
        self._changes = changes
        return apply_changes(pose.local, changes[None])[0]
