"""The lifted pose turned to agree with the image it came from (``convert``; ``stream`` runs
the same turns frame by frame: robot_retarget.keypoints.online_reprojection).

The keypoint model reads 2D keypoints and answers 3D rotations, and its bones do not project
back exactly onto the keypoints they came from. What the image does say, whatever the depth,
is the plane each bone lies in: the plane through the camera centre and the rays of the bone's
two end points. This module

1. estimates the camera from the lifted motion and the keypoints (:func:`estimate_camera`):
   its elevation, by projecting the lifted pose through each candidate and keeping the one
   under which its upper limbs and torso point where the keypoints' do, and its focal length
   from the image scale. Two things one image sequence cannot tell are assumed: the principal
   point is the performer's median hip centre in the image (the camera points at the
   performer), and the camera stands :data:`ASSUMED_DISTANCE_HEIGHTS` body heights away
   (about 5.5 m from a 1.7 m adult). The distance only sets how far the rays spread across the
   body: the README gives the error for cameras at 2.5 m and 8 m.
2. turns the torso (hip centre → shoulder centre, about the spine) into its plane, then each
   limb bone (upper arms, forearms, thighs, shins) by the smallest rotation that takes it
   toward its plane (:func:`plane_changes`): fully where the bone lies across the view, less where
   it points along the camera's axis, whose plane the keypoints' noise decides (the torso
   hardly ever does; weighting it too cost 0.3–0.6° on it on subjects 02 and 13). Hands, feet
   and toes follow their bones; the head and arms follow the torso.

The keypoints are smoothed over time first (Gaussian, σ = one 30 fps frame; a missing point
stays missing), a bone with an end point missing keeps the model's direction, and the turns
themselves are smoothed over time (:data:`CHANGE_SMOOTH_S`): they carry what noise the
keypoints still have, while the model's error they correct changes more slowly.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.coco17 import BODY_JOINTS, Coco
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import HumanMotion, skeleton_height
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.skeleton import Skeleton

ASSUMED_DISTANCE_HEIGHTS = 3.25
ELEVATIONS_DEG = np.arange(-20.0, 60.5, 1.0)  # candidates: training draws −10…45°
SMOOTH_S = 1.0 / 30.0
CHANGE_SMOOTH_S = 2.0 / 30.0
"""The turns are smoothed over time with this σ (on subjects 02, 05 and 13: the lifted
performer 6.05° with the turned pose smoothed as the keypoints are, 5.94° with the turns
smoothed at σ = 2 frames instead, 5.99° at 1, 5.96° at 3, 6.07° at 5)."""
ALONG_VIEW_SCALE = 0.4
"""A bone whose direction has image-plane length m (unit vector, camera frame) is turned a
share m² / (m² + ALONG_VIEW_SCALE²) of the way into its plane (chosen on subjects 02, 05, 13)."""

_BODY_K = np.array(list(BODY_JOINTS), dtype=np.int64)
_BODY_J = np.array(list(BODY_JOINTS.values()), dtype=np.int64)
LIMB_BONES: tuple[tuple[Joint, Joint, Coco, Coco], ...] = (
    (Joint.LeftArm, Joint.LeftForeArm, Coco.left_shoulder, Coco.left_elbow),
    (Joint.LeftForeArm, Joint.LeftHand, Coco.left_elbow, Coco.left_wrist),
    (Joint.RightArm, Joint.RightForeArm, Coco.right_shoulder, Coco.right_elbow),
    (Joint.RightForeArm, Joint.RightHand, Coco.right_elbow, Coco.right_wrist),
    (Joint.LeftUpLeg, Joint.LeftLeg, Coco.left_hip, Coco.left_knee),
    (Joint.LeftLeg, Joint.LeftFoot, Coco.left_knee, Coco.left_ankle),
    (Joint.RightUpLeg, Joint.RightLeg, Coco.right_hip, Coco.right_knee),
    (Joint.RightLeg, Joint.RightFoot, Coco.right_knee, Coco.right_ankle),
)
# What fits the camera: the upper arms and thighs, the shoulder and hip lines and the torso's
# sides (not the forearms and shins: wrists and ankles are the noisiest keypoints; on subjects
# 02, 05 and 13 leaving them out took the lifted performer from 6.18° to 6.16°, 6.07° → 6.04°
# with the turned pose smoothed).
_FIT_SEGMENTS = [(b[0], b[1]) for b in LIMB_BONES[::2]] + [
    (Joint.LeftArm, Joint.RightArm), (Joint.LeftUpLeg, Joint.RightUpLeg),
    (Joint.LeftUpLeg, Joint.LeftArm), (Joint.RightUpLeg, Joint.RightArm),
]  # fmt: skip
_FIT_KEYPOINTS = [(b[2], b[3]) for b in LIMB_BONES[::2]] + [
    (Coco.left_shoulder, Coco.right_shoulder), (Coco.left_hip, Coco.right_hip),
    (Coco.left_hip, Coco.left_shoulder), (Coco.right_hip, Coco.right_shoulder),
]  # fmt: skip
_FIT_STARTS, _FIT_ENDS = (np.array(c, dtype=np.int64) for c in zip(*_FIT_SEGMENTS, strict=True))
_FIT_KEY_STARTS, _FIT_KEY_ENDS = (
    np.array(c, dtype=np.int64) for c in zip(*_FIT_KEYPOINTS, strict=True)
)
_COST_CHUNK = 32
_LIMB_JOINTS, _LIMB_CHILDREN, _LIMB_KEY_STARTS, _LIMB_KEY_ENDS = (
    np.array(c, dtype=np.int64) for c in zip(*LIMB_BONES, strict=True)
)
# The joints whose local rotation the turns change: the spine's first joint (the torso) and
# the limb bones' (each turned, and the arms' parents turned with the torso). Hands, feet and
# toes keep their local rotations: they move with the bone they hang from.
CHANGED = np.array([Joint.Spine, *(b[0] for b in LIMB_BONES)], dtype=np.int64)


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


def _gaussian_in_time(
    values: FloatArray, weight: FloatArray, fps: float, sigma_s: float
) -> FloatArray:
    """``values`` (T, ...) averaged over time by a Gaussian of σ = ``sigma_s`` seconds, each
    frame counted by its ``weight`` (T, ...) (0: not seen); where nothing nearby was seen the
    result is 0."""
    sigma = sigma_s * fps
    radius = max(1, int(np.ceil(3.0 * sigma)))
    kernel = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)

    def conv(a: FloatArray) -> FloatArray:
        pad = np.pad(a, [(radius, radius)] + [(0, 0)] * (a.ndim - 1))
        out = np.zeros_like(a)
        for i, k in enumerate(kernel):
            out += k * pad[i : i + a.shape[0]]
        return out

    total = conv(weight)
    return np.asarray(conv(values * weight[..., None]) / np.maximum(total, 1e-12)[..., None])


def smooth_keypoints(xy: FloatArray, valid: BoolArray, fps: float) -> FloatArray:
    """``xy`` (T, 17, 2) smoothed over time by a Gaussian of σ = :data:`SMOOTH_S` seconds,
    over the frames where each point is seen (missing points stay NaN)."""
    w = np.asarray(valid, dtype=np.float64)
    smoothed = _gaussian_in_time(np.where(w[..., None] > 0, xy, 0.0), w, fps, SMOOTH_S)
    return np.where(w[..., None] > 0, smoothed, np.nan)


def smooth_rotations(rotations: FloatArray, fps: float, sigma_s: float) -> FloatArray:
    """Rotations (T, J, 4) smoothed over time by a Gaussian of σ = ``sigma_s`` seconds (each
    joint's quaternions made continuous, averaged, normalised)."""
    q = quat.make_continuous(rotations, axis=0)
    smoothed = _gaussian_in_time(q, np.ones(q.shape[:-1]), fps, sigma_s)
    return np.asarray(smoothed / np.linalg.norm(smoothed, axis=-1, keepdims=True))


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
    points, offsets free) of the frames with three or more body points seen."""
    obs = xy[:, _BODY_K]
    w = np.asarray(np.isfinite(obs).all(axis=-1), dtype=np.float64)
    frames = w.sum(axis=1) >= 3.0  # a scale and an offset need a few points
    proj = _project(rel[frames][:, _BODY_J], rot[None], distance)[0]
    obs, w = np.nan_to_num(obs[frames]), w[frames]
    n = np.maximum(w.sum(axis=1), 1.0)[:, None, None]
    obs_c = obs - (obs * w[..., None]).sum(axis=1, keepdims=True) / n
    proj_c = proj - (proj * w[..., None]).sum(axis=1, keepdims=True) / n
    num = ((proj_c * obs_c).sum(-1) * w).sum(1)
    return np.asarray(num / np.maximum(((proj_c * proj_c).sum(-1) * w).sum(1), 1e-12))


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
    distance = camera_distance(motion.skeleton)
    pos = motion.positions()
    rel: FloatArray = np.asarray(pos - pos[:, :1])
    obs = np.asarray(xy, dtype=np.float64)
    rots = candidate_rotations()
    costs = np.zeros(len(rots))
    for t in range(0, len(rel), _COST_CHUNK):  # bounded memory on long clips
        costs += direction_costs(rel[t : t + _COST_CHUNK], obs[t : t + _COST_CHUNK], rots, distance)
    seen = np.isfinite(obs[:, _FIT_KEY_ENDS] - obs[:, _FIT_KEY_STARTS]).all(axis=-1)
    if not seen.any():
        return None
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


def _into_planes(
    directions: FloatArray, ray_a: FloatArray, ray_b: FloatArray, weighted: bool = True
) -> FloatArray:
    """Unit ``directions`` (T, 3, camera frame) turned toward the planes spanned by the rays
    (T, 3) (weighted by how much each lies across the view); NaN rays leave them as they are."""
    normal = quat.cross(ray_a, ray_b)
    size = np.linalg.norm(normal, axis=-1, keepdims=True)
    ok = np.isfinite(size[:, 0]) & (size[:, 0] > 1e-9)
    normal = np.where(ok[:, None], normal / np.where(ok[:, None], size, 1.0), 0.0)
    inside = directions - np.sum(directions * normal, axis=-1, keepdims=True) * normal
    if weighted:
        m2 = np.sum(directions[:, :2] ** 2, axis=-1, keepdims=True)
        inside = directions + m2 / (m2 + ALONG_VIEW_SCALE**2) * (inside - directions)
    length = np.linalg.norm(inside, axis=-1, keepdims=True)
    ok &= length[:, 0] > 1e-9
    out: FloatArray = np.where(ok[:, None], inside / np.where(ok[:, None], length, 1.0), directions)
    return out


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=np.float64)


def reproject(motion: HumanMotion, sequence: KeypointSequence) -> HumanMotion:
    """``motion`` (the keypoint model's answer for ``sequence``, frame for frame, heading frame)
    with its torso and limb bones turned toward the planes the image puts them in (module
    docstring); as it is where the keypoints cannot tell the camera (:func:`estimate_camera`)."""
    if motion.num_frames != sequence.num_frames:
        raise ValueError(f"motion has {motion.num_frames} frames, keypoints {sequence.num_frames}")
    xy = smooth_keypoints(sequence.xy, sequence.valid, sequence.fps)
    camera = estimate_camera(motion, xy)
    if camera is None:
        return motion
    pose = MatrixPose.of(motion.skeleton, np.asarray(motion.local_quats))
    # The turns carry what noise the smoothed keypoints still have; the model's error they
    # correct changes more slowly: they are smoothed again, over a longer time.
    changes = smooth_rotations(plane_changes(pose, xy, camera), motion.fps, CHANGE_SMOOTH_S)
    local = apply_changes(pose.local, changes)
    return HumanMotion(
        motion.skeleton, local, motion.root_pos, motion.fps, source_path=motion.source_path
    )


@dataclass(frozen=True)
class MatrixPose:
    """Frames of a pose as rotation matrices: ``local`` quaternions (T, 22, 4) and their
    global rotation matrices (T, 22, 3, 3) and joint positions (T, 22, 3), root at the origin.
    Matrices because one live frame is a few dozen small products (quaternion products cost
    several numpy calls each)."""

    skeleton: Skeleton
    local: FloatArray
    global_m: FloatArray
    positions: FloatArray

    @classmethod
    def of(cls, skeleton: Skeleton, local: FloatArray) -> MatrixPose:
        local_m = quat.to_matrix(local)
        glob = np.empty_like(local_m)
        pos = np.zeros((*local.shape[:-1], 3))
        glob[:, 0] = local_m[:, 0]
        offsets = skeleton.offsets
        for idx, par in skeleton.depth_levels:  # one batched product per tree depth
            parent = glob[:, par]
            pos[:, idx] = pos[:, par] + (parent @ offsets[idx][..., None])[..., 0]
            glob[:, idx] = parent @ local_m[:, idx]
        return cls(skeleton, local, glob, pos)


def _turns(a: FloatArray, b: FloatArray) -> FloatArray:
    """Rotation matrices (..., 3, 3) taking unit vectors ``a`` onto unit vectors ``b`` by the
    shortest arc (Rodrigues: c·I + [v]× + v vᵀ / (1 + c), v = a × b, c = a · b). The turns here
    never reach 90°: a direction is moved toward a plane it makes less than 90° with."""
    v = quat.cross(a, b)
    c = np.sum(a * b, axis=-1)[..., None, None]
    padded = np.concatenate([v, np.zeros((*v.shape[:-1], 1))], axis=-1)  # index 3 is 0
    skew = (padded[..., _SKEW_INDEX] * _SKEW_SIGN).reshape(*v.shape, 3)
    outer = v[..., :, None] * v[..., None, :]
    return np.asarray(c * np.eye(3) + skew + outer / np.maximum(1.0 + c, 1e-12))


_SKEW_INDEX = np.array([3, 2, 1, 2, 3, 0, 1, 0, 3])
_SKEW_SIGN = np.array([0.0, -1.0, 1.0, 1.0, 0.0, -1.0, -1.0, 1.0, 0.0])
# a ⊗ b = (a[_LEFT_INDEX] · _LEFT_SIGN) @ b: one product instead of the sixteen of quat.mul.
_LEFT_INDEX = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_LEFT_SIGN = np.array(
    [[1.0, -1.0, -1.0, -1.0], [1.0, 1.0, -1.0, 1.0], [1.0, 1.0, 1.0, -1.0], [1.0, -1.0, 1.0, 1.0]]
)


def apply_changes(local: FloatArray, changes: FloatArray) -> FloatArray:
    """Local rotations (T, 22, 4) with :data:`CHANGED` joints' turned by ``changes``
    (T, len(CHANGED), 4), each applied on the left of its joint's local rotation."""
    out = np.array(local)
    left = changes[..., _LEFT_INDEX] * _LEFT_SIGN  # change ⊗ · as a matrix
    turned = (left @ out[:, CHANGED][..., None])[..., 0]
    out[:, CHANGED] = turned / np.linalg.norm(turned, axis=-1, keepdims=True)
    return out


def plane_changes(pose: MatrixPose, xy: FloatArray, camera: CameraEstimate) -> FloatArray:
    """How ``pose`` (heading frame) turns with the torso and then each limb bone turned toward
    the planes of the keypoints ``xy`` (T, 17, 2) seen by ``camera`` (module docstring): the
    changes (T, len(CHANGED), 4, w > 0) of the :data:`CHANGED` joints' local rotations, for
    :func:`apply_changes` (the other joints' do not change)."""
    rot = camera.rotation()
    glob = pose.global_m.copy()
    pos = pose.positions
    # The torso: hip centre → shoulder centre, turned about the spine with everything above it.
    # (The spine's joint is not the hip centre, so the turn lands near the plane, not on it; a
    # second turn onto it scored 0.01–0.05° worse overall on subjects 02 and 13.)
    hip2 = 0.5 * (xy[:, Coco.left_hip] + xy[:, Coco.right_hip])
    shoulder2 = 0.5 * (xy[:, Coco.left_shoulder] + xy[:, Coco.right_shoulder])
    hip3 = 0.5 * (pos[:, Joint.LeftUpLeg] + pos[:, Joint.RightUpLeg])
    shoulder3 = 0.5 * (pos[:, Joint.LeftArm] + pos[:, Joint.RightArm])
    before = _unit(shoulder3 - hip3) @ rot.T
    after = _into_planes(before, camera.rays(hip2), camera.rays(shoulder2), weighted=False)
    upper = _upper_body(pose.skeleton)
    glob[:, upper] = _turns(before @ rot, after @ rot)[:, None] @ glob[:, upper]

    # Each limb bone on its own (its child keeps its global rotation), all in one pass.
    t, n = glob.shape[0], len(LIMB_BONES)
    bone = (glob[:, _LIMB_JOINTS] @ pose.skeleton.offsets[_LIMB_CHILDREN][..., None])[..., 0]
    before = (_unit(bone) @ rot.T).reshape(t * n, 3)
    ray_a = camera.rays(xy[:, _LIMB_KEY_STARTS]).reshape(t * n, 3)
    ray_b = camera.rays(xy[:, _LIMB_KEY_ENDS]).reshape(t * n, 3)
    after = _into_planes(before, ray_a, ray_b)
    turn = _turns(before @ rot, after @ rot).reshape(t, n, 3, 3)
    glob[:, _LIMB_JOINTS] = turn @ glob[:, _LIMB_JOINTS]

    # Only the spine and the limb joints' local rotations change (the rest turned with their
    # parents, or keep theirs: hands, feet, toes). Each change is a turn of under 180° (at
    # most two turns of under 90°), so its quaternion comes from the trace, w > 0, and the
    # result stays in its joint's hemisphere.
    parents = [pose.skeleton.parents[j] for j in CHANGED]
    before_m = np.swapaxes(pose.global_m[:, parents], -1, -2) @ pose.global_m[:, CHANGED]
    after_m = np.swapaxes(glob[:, parents], -1, -2) @ glob[:, CHANGED]
    change = after_m @ np.swapaxes(before_m, -1, -2)
    trace = change[..., 0, 0] + change[..., 1, 1] + change[..., 2, 2]
    if (trace < -0.9).any():  # past ~160°: Shepperd's method, robust everywhere
        q_change = quat.from_matrix(change)
    else:
        w = 0.5 * np.sqrt(1.0 + trace)
        q_change = np.stack(
            [
                w,
                (change[..., 2, 1] - change[..., 1, 2]) / (4.0 * w),
                (change[..., 0, 2] - change[..., 2, 0]) / (4.0 * w),
                (change[..., 1, 0] - change[..., 0, 1]) / (4.0 * w),
            ],
            axis=-1,
        )
    return np.asarray(q_change)


def _upper_body(skeleton: Skeleton) -> list[int]:
    return _subtree(skeleton.parents, int(Joint.Spine))


def _subtree(parents: tuple[int, ...], root: int) -> list[int]:
    """``root`` and every joint below it (parents come first)."""
    inside = {root}
    for j, p in enumerate(parents):
        if p in inside:
            inside.add(j)
    return sorted(inside)
