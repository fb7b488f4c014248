"""The image's planes for ``stream``: :mod:`robot_retarget.keypoints.reprojection` one camera
frame at a time, the camera (:mod:`robot_retarget.keypoints.camera_fit`) fitted so far.

``convert`` fits the camera on the whole clip and smooths the keypoints with the frames after
each one; a live stream has neither. Here the camera is fitted on the frames so far: the
candidate elevations' direction costs are sums over frames, so they are kept as running sums;
the image scale is a running mean of its logarithm. The principal point is the image centre
where the image size is known (``image_size``), else a running mean of the hip centre,
which is slow to settle for a performer who crosses the image. The lifted performer with the
running mean → the image centre (the stream's causal model, every second or third clip through
the 12 evaluation views): validation subjects 06, 08, 12, who walk about, 8.43° → 8.15° (the
whole clip's median hip centre: 8.13°); the fold models' held-out 02 and 05 18.70° → 18.63°,
13 and 14, who stay in place, 14.13° either way. ``convert`` keeps the whole clip's median
hip centre (the image centre: 7.10° against 7.07° on the validation clips). Until
:data:`MIN_SECONDS` of frames have shown a body the pose passes through as
the model gave it. The keypoints are used as they arrive (no smoothing: it would look ahead or lag).

As in ``convert``, the upper arms, thighs and shins also take their angle to the image plane
from their image length (reprojection.depth_from_length), against this frame's image scale.

A frame runs as three compiled calls (robot_retarget.keypoints.planes_graph: about a tenth of
the time of the numpy code, which stays as the reference, ``compiled=False``).
"""

from __future__ import annotations

import math

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.casadi_jit import CompiledFunction
from robot_retarget.keypoints.camera_fit import (
    ELEVATIONS_DEG,
    CameraEstimate,
    camera_distance,
    candidate_rotations,
    direction_costs,
    image_scales,
)
from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.keypoints.planes_graph import fit_function, scale_function, turn_function
from robot_retarget.keypoints.reprojection import (
    CHANGED,
    MatrixPose,
    apply_changes,
    plane_changes,
)
from robot_retarget.keypoints.sequence import check_image_size, image_centre
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton

MIN_SECONDS = 0.2
"""Frames with a body seen for this long before the camera is trusted (6 at 30 fps). Short:
the causal model is least sure in a stream's first frames, where the turns help most (on
subjects 02 and 13, the lifted performer 8.94° / 7.61° with 0.5 s, 8.68° / 7.45° with 0.2 s,
8.60° / 7.40° with 0.1 s, 8.57° / 7.38° with one frame), but not too short: on the robots
(three of those clips through four views) 0.1 s cost OP3 0.8° (15.88° against 15.06° / 15.02°
with 0.2 / 0.5 s: an early camera still off puts an arm on another branch), Poppy the same
at each (6.26° / 6.27° / 6.25°). The turns fade in, so the camera's first estimate does not
jolt the pose."""
CHANGE_RATE = 0.3
"""At 30 fps each frame's turns move the applied ones this share of the way (an exponential
average: the keypoints' frame-to-frame noise is in the turns, the model's error they correct
is not); at other frame rates the share with the same time constant (chosen on subjects 02
and 13: 0.5 / 0.3 / 0.2 / 0.1 gave 6.61° / 6.62° / 6.72° / 6.94°)."""
_RATE_FPS = 30.0


class OnlineReprojection:
    """``step(local (22, 4), xy (17, 2, NaN where missing)) → (22, 4)``: the model's answer
    for one camera frame turned into the image's planes, the camera fitted on the frames so
    far (module docstring). ``reset()`` forgets the camera (a new sender, maybe a new one).
    ``compiled=False`` runs the numpy reference instead of the compiled graphs.
    ``image_size`` (width, height px): its centre is the principal point (module docstring);
    it may be given later (:meth:`set_image_size`)."""

    def __init__(
        self,
        skeleton: Skeleton | None = None,
        fps: float = 30.0,
        *,
        compiled: bool = True,
        image_size: tuple[float, float] | None = None,
    ) -> None:
        if not (math.isfinite(fps) and fps > 0.0):
            raise ValueError(f"fps must be positive, got {fps}")
        self.skeleton = skeleton or default_canonical_skeleton()
        self.min_frames = max(1, round(MIN_SECONDS * fps))
        self.rate = 1.0 - (1.0 - CHANGE_RATE) ** (_RATE_FPS / fps)
        self._rots = candidate_rotations()
        self._distance = camera_distance(self.skeleton)
        self._calls = _PlanesCalls(self.skeleton, self._distance) if compiled else None
        self._take_image_size(image_size)
        self.reset()

    @property
    def principal_px(self) -> FloatArray | None:
        """The known principal point (the image centre), or None: the hips' running mean."""
        return self._principal

    def _take_image_size(self, image_size: tuple[float, float] | None) -> None:
        self._image_size = None if image_size is None else check_image_size(image_size)
        self._principal = image_centre(self._image_size)  # computed once, read every frame

    def set_image_size(self, image_size: tuple[float, float] | None) -> None:
        """The image's width and height in pixels (None: unknown). A different size is another
        camera or resolution: the camera fitted so far is forgotten; the same one costs a tuple
        comparison (a live sender may send it with every frame)."""
        if image_size == self._image_size:
            return
        self._take_image_size(image_size)
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
        principal = self._principal
        if principal is None:
            principal = self._hips / self._hips_seen
        return CameraEstimate(math.radians(ELEVATIONS_DEG[best]), focal, principal, self._distance)

    def step(self, local: FloatArray, xy: FloatArray) -> FloatArray:
        if self._calls is not None:
            return self._compiled_step(local, xy)
        pose = MatrixPose.of(self.skeleton, np.asarray(local, dtype=np.float64)[None])
        obs = np.asarray(xy, dtype=np.float64)[None]
        rel = pose.positions  # the root is at the origin
        self._add_costs(direction_costs(rel, obs, self._rots, self._distance))
        scale = image_scales(rel, obs, self._rots[int(np.argmin(self._costs))], self._distance)
        frame_scale = float(scale[0]) if len(scale) else math.nan
        hips = 0.5 * (obs[0, Coco.left_hip] + obs[0, Coco.right_hip])
        self._count_frame(frame_scale, len(scale) > 0, hips)
        camera = self.camera
        if camera is None:
            return pose.local[0]
        changes = plane_changes(pose, obs, camera, image_scale=np.array([frame_scale]))[0]
        if self._changes is None:  # the turns fade in from none: no jolt when the camera is set
            self._changes = _NO_TURN.reshape(-1, 4)
        # Both have w > 0: a normalised lerp is a fine average.
        changes = self._changes + self.rate * (changes - self._changes)
        changes /= np.linalg.norm(changes, axis=-1, keepdims=True)
        self._changes = changes
        return apply_changes(pose.local, changes[None])[0]

    def _add_costs(self, costs: FloatArray) -> None:
        # Running sums: one frame's overflow would stay in them for good (the glitch gate
        # refuses such coordinates first; this keeps the fit whatever reaches it).
        if np.isfinite(costs).all():
            self._costs += costs

    def _count_frame(self, scale: float, enough: bool, hips: FloatArray) -> None:
        if enough and math.isfinite(scale) and scale > 0.0:
            self._log_scale += math.log(scale)
            self._scales += 1
        if np.isfinite(hips).all():
            self._hips += hips
            self._hips_seen += 1

    def _compiled_step(self, local: FloatArray, xy: FloatArray) -> FloatArray:
        """:meth:`step` through the compiled graphs (the same numbers to rounding)."""
        g = self._calls
        assert g is not None
        obs = np.asarray(xy, dtype=np.float64)
        seen: BoolArray = np.asarray(np.isfinite(obs).all(axis=-1), dtype=bool)
        g.local[:] = np.asarray(local, dtype=np.float64).reshape(-1)
        g.xy[:] = np.where(seen[:, None], obs, 0.0).reshape(-1)
        g.seen[:] = seen
        g.fit()
        self._add_costs(g.costs)
        g.rotation[:] = self._rots[int(np.argmin(self._costs))].reshape(-1)
        g.scale()
        scale, enough = float(g.scale_out[0]), bool(g.enough[0] > 0.5)
        hips = 0.5 * (obs[Coco.left_hip] + obs[Coco.right_hip])
        self._count_frame(scale, enough, hips)
        camera = self.camera
        if camera is None:
            return g.local.reshape(-1, 4).copy()
        g.turn_rotation[:] = camera.rotation().reshape(-1)
        g.image_scale[0] = scale if enough and math.isfinite(scale) else 0.0
        g.camera[:2] = camera.principal_px
        g.camera[2] = camera.focal_px
        g.applied[:] = _NO_TURN if self._changes is None else self._changes.reshape(-1)
        g.rate[0] = self.rate
        g.turn()
        self._changes = g.applied_next.reshape(-1, 4).copy()
        return g.turned.reshape(-1, 4).copy()


# The turns fade in from none (see step): the identity for every changed joint.
_NO_TURN = np.tile([1.0, 0.0, 0.0, 0.0], len(CHANGED))


class _PlanesCalls:
    """The three compiled graphs of one skeleton, their arrays bound once and shared (the
    fit's positions and the keypoints are the scale's and the turn's arguments)."""

    def __init__(self, skeleton: Skeleton, distance: float) -> None:
        parents = tuple(int(p) for p in skeleton.parents)
        offsets = np.asarray(skeleton.offsets, dtype=np.float64)
        self.fit = CompiledFunction(fit_function(parents, offsets, distance))
        self.local, self.xy, self.seen = self.fit.args
        positions, self.costs = self.fit.res
        self.scale = CompiledFunction(
            scale_function(distance), args=[positions, self.xy, self.seen, None]
        )
        self.rotation = self.scale.args[3]
        self.scale_out, self.enough = self.scale.res
        self.turn = CompiledFunction(
            turn_function(parents, offsets, distance),
            args=[self.local, self.xy, self.seen, None, None, None, None, None],
        )
        args = self.turn.args
        self.turn_rotation, self.camera, self.applied, self.rate, self.image_scale = args[3:]
        self.turned, self.applied_next = self.turn.res
