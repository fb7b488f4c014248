"""The lifted pose turned to agree with the image it came from (``convert``).

The keypoint model reads 2D keypoints and answers 3D rotations, and its bones do not project
back exactly onto the keypoints they came from. What the image does say, whatever the depth,
is the plane each bone lies in: the plane through the camera centre and the rays of the bone's
two end points. This module

1. estimates the camera from the lifted motion and the keypoints (:func:`estimate_camera`):
   its elevation, by projecting the lifted pose through each candidate and keeping the one
   under which its bones point where the keypoints' do, and its focal length from the image
   scale. Two things one image sequence cannot tell are assumed: the principal point
   is the performer's median hip centre in the image (the camera points at the performer), and
   the camera stands :data:`ASSUMED_DISTANCE_HEIGHTS` body heights away (about 5.5 m from a
   1.7 m adult). The distance only sets how far the rays spread across the body: the README
   gives the error for cameras at 2.5 m and 8 m.
2. turns the torso (hip centre → shoulder centre, about the spine) into its plane, then each
   limb bone (upper arms, forearms, thighs, shins) by the smallest rotation that takes it
   toward its plane (:func:`reproject`): fully where the bone lies across the view, less where
   it points along the camera's axis, whose plane the keypoints' noise decides (the torso
   hardly ever does; weighting it too cost 0.3–0.6° on it on subjects 02 and 13). Hands, feet
   and toes follow their bones; the head and arms follow the torso.

The keypoints are smoothed over time first (Gaussian, σ = one 30 fps frame; a missing point
stays missing), and a bone with an end point missing keeps the model's direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.coco17 import BODY_JOINTS, Coco
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import HumanMotion, skeleton_height
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.skeleton import local_from_global

ASSUMED_DISTANCE_HEIGHTS = 3.25
ELEVATIONS_DEG = np.arange(-20.0, 60.5, 1.0)  # candidates: training draws −10…45°
SMOOTH_S = 1.0 / 30.0
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
# What fits the camera: the limb bones, the shoulder and hip lines and the torso's sides.
_FIT_SEGMENTS = [(b[0], b[1]) for b in LIMB_BONES] + [
    (Joint.LeftArm, Joint.RightArm), (Joint.LeftUpLeg, Joint.RightUpLeg),
    (Joint.LeftUpLeg, Joint.LeftArm), (Joint.RightUpLeg, Joint.RightArm),
]  # fmt: skip
_FIT_KEYPOINTS = [(b[2], b[3]) for b in LIMB_BONES] + [
    (Coco.left_shoulder, Coco.right_shoulder), (Coco.left_hip, Coco.right_hip),
    (Coco.left_hip, Coco.left_shoulder), (Coco.right_hip, Coco.right_shoulder),
]  # fmt: skip
_FOLLOWERS = (  # keep their local rotations: they move with the bone they hang from
    Joint.LeftHand, Joint.RightHand, Joint.LeftFoot, Joint.RightFoot,
    Joint.LeftToeBase, Joint.RightToeBase,
)  # fmt: skip


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
        cam = VirtualCamera(0.0, self.elevation_rad, self.distance_m, self.focal_px)
        return cam.pose(np.zeros(3))[1]

    def rays(self, xy: FloatArray) -> FloatArray:
        """Pixels (..., 2) → viewing rays (..., 3) in camera coordinates (not unit)."""
        p = np.asarray(xy, dtype=np.float64) - self.principal_px
        return np.concatenate([p, np.full((*p.shape[:-1], 1), self.focal_px)], axis=-1)


def smooth_keypoints(xy: FloatArray, valid: BoolArray, fps: float) -> FloatArray:
    """``xy`` (T, 17, 2) smoothed over time by a Gaussian of σ = :data:`SMOOTH_S` seconds,
    over the frames where each point is seen (missing points stay NaN)."""
    sigma = SMOOTH_S * fps
    radius = max(1, int(np.ceil(3.0 * sigma)))
    kernel = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    w = np.asarray(valid, dtype=np.float64)
    filled = np.where(w[..., None] > 0, xy, 0.0)

    def conv(a: FloatArray) -> FloatArray:
        pad = np.pad(a, [(radius, radius)] + [(0, 0)] * (a.ndim - 1))
        out = np.zeros_like(a)
        for i, k in enumerate(kernel):
            out += k * pad[i : i + a.shape[0]]
        return out

    weight = conv(w)
    smoothed = conv(filled) / np.maximum(weight, 1e-12)[..., None]
    return np.where(w[..., None] > 0, smoothed, np.nan)


def _project(body: FloatArray, elevation: float, distance: float) -> FloatArray:
    """Points (..., 3) relative to the hips, heading frame → image (..., 2) at unit focal length
    over ``distance`` (x right, y down)."""
    rot = VirtualCamera(0.0, elevation, distance, 1.0).pose(np.zeros(3))[1]
    cam = body @ rot.T
    return np.asarray(cam[..., :2] / (1.0 + cam[..., 2:] / distance), dtype=np.float64)


def estimate_camera(motion: HumanMotion, xy: FloatArray) -> CameraEstimate | None:
    """The camera (module docstring) that best reprojects ``motion`` (the keypoint model's
    answer, heading frame) onto ``xy`` (T, 17, 2, NaN where missing); None where the keypoints
    cannot tell (no bone seen at both ends, no frame with three body points, no positive
    image scale).

    The elevation is the one under which the lifted bones' image directions best match the
    keypoints' (each bone weighted by its length in the image). Directions, not positions: the
    performer's proportions are not the reference skeleton's, and a fit of positions tilts the
    camera to make up the difference (on subjects 02 and 13 its elevation was 5–17° off at
    30°, the directions' 1–10°). The focal length then comes from the per-frame image scale."""
    distance = ASSUMED_DISTANCE_HEIGHTS * skeleton_height(motion.skeleton)
    pos = motion.positions()
    rel: FloatArray = np.asarray(pos - pos[:, :1])  # from the hips
    obs = np.asarray(xy, dtype=np.float64)
    starts, ends = (np.array(c, dtype=np.int64) for c in zip(*_FIT_SEGMENTS, strict=True))
    k_starts, k_ends = (np.array(c, dtype=np.int64) for c in zip(*_FIT_KEYPOINTS, strict=True))
    seen_vec = obs[:, k_ends] - obs[:, k_starts]  # (T, S, 2)
    seen_len = np.linalg.norm(np.nan_to_num(seen_vec), axis=-1)
    weight = np.where(np.isfinite(seen_vec).all(axis=-1), seen_len, 0.0)
    if not weight.any():
        return None
    seen_dir = np.nan_to_num(seen_vec) / np.maximum(seen_len, 1e-9)[..., None]
    best: tuple[float, float] | None = None
    for elevation in np.radians(ELEVATIONS_DEG):
        proj = _project(rel, float(elevation), distance)
        vec = proj[:, ends] - proj[:, starts]
        unit = vec / np.maximum(np.linalg.norm(vec, axis=-1, keepdims=True), 1e-12)
        cost = float((weight * (1.0 - (unit * seen_dir).sum(axis=-1))).sum())
        if best is None or cost < best[0]:
            best = (cost, float(elevation))
    assert best is not None
    elevation = best[1]
    # Per-frame image scale (pixels per metre at the hips' depth) by least squares.
    body_obs = obs[:, _BODY_K]
    w: FloatArray = np.asarray(np.isfinite(body_obs).all(axis=-1), dtype=np.float64)
    frames = w.sum(axis=1) >= 3.0  # a scale and an offset need a few points
    if not frames.any():
        return None
    proj = _project(rel[:, _BODY_J], elevation, distance)[frames]
    body_obs, w = np.nan_to_num(body_obs[frames]), w[frames]
    n = np.maximum(w.sum(axis=1), 1.0)[:, None, None]
    obs_c = body_obs - (body_obs * w[..., None]).sum(axis=1, keepdims=True) / n
    proj_c = proj - (proj * w[..., None]).sum(axis=1, keepdims=True) / n
    scale = ((proj_c * obs_c).sum(-1) * w).sum(1) / np.maximum(
        ((proj_c * proj_c).sum(-1) * w).sum(1), 1e-12
    )
    focal = float(np.median(scale)) * distance
    if not (np.isfinite(focal) and focal > 0.0):
        return None
    hips = 0.5 * (obs[:, Coco.left_hip] + obs[:, Coco.right_hip])
    seen = np.isfinite(hips).all(axis=-1)
    principal = np.median(hips[seen] if seen.any() else obs[np.isfinite(obs).all(-1)], axis=0)
    return CameraEstimate(elevation, focal, principal, distance)


def _into_planes(
    directions: FloatArray, ray_a: FloatArray, ray_b: FloatArray, weighted: bool = True
) -> FloatArray:
    """Unit ``directions`` (T, 3, camera frame) turned toward the planes spanned by the rays
    (T, 3) (weighted by how much each lies across the view); NaN rays leave them as they are."""
    normal = np.cross(ray_a, ray_b)
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
    rot = camera.rotation()
    skel = motion.skeleton
    glob = motion.global_quats().copy()

    # The torso: hip centre → shoulder centre, turned about the spine with everything above it.
    # (The spine's joint is not the hip centre, so the turn lands near the plane, not on it; a
    # second turn onto it scored 0.01–0.05° worse overall on subjects 02 and 13.)
    hip2 = 0.5 * (xy[:, Coco.left_hip] + xy[:, Coco.right_hip])
    shoulder2 = 0.5 * (xy[:, Coco.left_shoulder] + xy[:, Coco.right_shoulder])
    torso_rays = (camera.rays(hip2), camera.rays(shoulder2))
    upper = _subtree(skel.parents, int(Joint.Spine))
    pos = motion.positions()
    hip3 = 0.5 * (pos[:, Joint.LeftUpLeg] + pos[:, Joint.RightUpLeg])
    shoulder3 = 0.5 * (pos[:, Joint.LeftArm] + pos[:, Joint.RightArm])
    before = _unit(shoulder3 - hip3) @ rot.T
    after = _into_planes(before, *torso_rays, weighted=False)
    turn = quat.from_two_vectors(before @ rot, after @ rot)
    glob[:, upper] = quat.mul(turn[:, None], glob[:, upper])

    # Each limb bone, on its own: its child keeps its global rotation until its own turn.
    for joint, child, start, end in LIMB_BONES:
        bone = quat.rotate(glob[:, joint], skel.offsets[child])
        before = _unit(bone) @ rot.T
        after = _into_planes(before, camera.rays(xy[:, start]), camera.rays(xy[:, end]))
        glob[:, joint] = quat.mul(quat.from_two_vectors(before @ rot, after @ rot), glob[:, joint])

    local = local_from_global(skel, glob)
    follow = list(_FOLLOWERS)
    local[:, follow] = np.asarray(motion.local_quats)[:, follow]
    return HumanMotion(skel, local, motion.root_pos, motion.fps, source_path=motion.source_path)


def _subtree(parents: tuple[int, ...], root: int) -> list[int]:
    """``root`` and every joint below it (parents come first)."""
    inside = {root}
    for j, p in enumerate(parents):
        if p in inside:
            inside.add(j)
    return sorted(inside)
