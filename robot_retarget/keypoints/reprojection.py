"""The lifted pose turned to agree with the image it came from (``convert``; ``stream`` runs
the same turns frame by frame: robot_retarget.keypoints.online_reprojection).

The keypoint model reads 2D keypoints and answers 3D rotations, and its bones do not project
back exactly onto the keypoints they came from. What the image does say, whatever the depth,
is the plane each bone lies in: the plane through the camera centre and the rays of the bone's
two end points. This module

1. estimates the camera from the lifted motion and the keypoints
   (robot_retarget.keypoints.camera_fit);
2. turns the torso (hip centre → shoulder centre, about the spine) into its plane, then each
   limb bone (upper arms, forearms, thighs, shins) by the smallest rotation that takes it
   toward its plane (:func:`plane_changes`): fully where the bone lies across the view, less
   where it points along the camera's axis, whose plane the keypoints' noise decides (the torso
   hardly ever does; weighting it too cost 0.3–0.6° on it on subjects 02 and 13), and onto the
   side of the view its keypoints put it (a bone points from its first keypoint toward its
   second across the image: :func:`_image_side`). Hands, feet and toes follow their bones;
   the head and arms follow the torso;
3. moves the upper arms', thighs' and shins' angle to the image plane toward the one their
   image length gives (:func:`depth_from_length`: the planes fix a bone's direction across the
   image, not how far it points toward or away from the camera).

The keypoints are smoothed over time first (Gaussian, σ = one 30 fps frame; a missing point
stays missing), a bone with an end point missing keeps the model's direction, and the turns
themselves are smoothed over time (:data:`CHANGE_SMOOTH_S`): they carry what noise the
keypoints still have, while the model's error they correct changes more slowly.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.camera_fit import CameraEstimate, fit_camera, frame_scales
from robot_retarget.keypoints.coco17 import LIMB_BONES, Coco
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.runtime.frame import TreeKinematics, matrices, qmul
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.skeleton import Skeleton

SMOOTH_S = 1.0 / 30.0
CHANGE_SMOOTH_S = 2.0 / 30.0
"""The turns are smoothed over time with this σ (on subjects 02, 05 and 13: the lifted
performer 6.05° with the turned pose smoothed as the keypoints are, 5.94° with the turns
smoothed at σ = 2 frames instead, 5.99° at 1, 5.96° at 3, 6.07° at 5)."""
ALONG_VIEW_SCALE = 0.25
"""A bone whose direction has image-plane length m (unit vector, camera frame) is turned a
share m² / (m² + ALONG_VIEW_SCALE²) of the way into its plane (0.4 until 2026-11-27, chosen on
subjects 02, 05, 13, which the keypoint models train on; 0.25 chosen with DEPTH_SCALE)."""
DEPTH_SCALE = 1.0
"""The depth cue's share scale (:func:`depth_from_length`): the upper arms, thighs and shins
(:data:`DEPTH_BONES`) also take their angle to the image plane from their image length against
the frame's image scale × their length on the reference skeleton (the performer's proportions
are not estimated: in ``stream`` a running estimate from the longest images scored worse).
Chosen with ALONG_VIEW_SCALE on subjects the lifting model never saw: two causal models of the
shipped recipe trained without 13, 14 and without 02, 05 (with the validation subjects: the
training ignored ``--exclude-subjects`` then), each scored on its held-out pair, and the
shipped models on 02, 05, 13 (the lifted performer through 12 views; ``stream``: 14.33° →
13.90°, 19.98° → 19.57°, 9.14° → 8.97°; ``convert``'s planes on the fold models' whole-clip
answers and on the shipped ensemble: 13.96° → 13.46°, 19.52° → 19.03°, 8.03° → 7.89°). A share
scale of 0.5 or 2, or the cue on the forearms too, did worse on one of the three."""

_LIMB_JOINTS, _LIMB_CHILDREN, _LIMB_KEY_STARTS, _LIMB_KEY_ENDS = (
    np.array(c, dtype=np.int64) for c in zip(*LIMB_BONES, strict=True)
)
# The limb bones that take the depth cue: upper arms, thighs and shins, not the forearms (the
# wrists are the noisiest keypoints: with them the forearms' error rose while every other
# bone's fell).
DEPTH_BONES = np.array(
    [b[0] not in (Joint.LeftForeArm, Joint.RightForeArm) for b in LIMB_BONES], dtype=bool
)


# The joints whose local rotation the turns change: the spine's first joint (the torso) and
# the limb bones' (each turned, and the arms' parents turned with the torso). Hands, feet and
# toes keep their local rotations: they move with the bone they hang from.
CHANGED = np.array([Joint.Spine, *(b[0] for b in LIMB_BONES)], dtype=np.int64)


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


def _into_planes(
    directions: FloatArray, ray_a: FloatArray, ray_b: FloatArray, weighted: bool = True
) -> FloatArray:
    """Unit ``directions`` (T, 3, camera frame) turned toward the planes spanned by the rays
    (T, 3) (weighted by how much each lies across the view), then onto the side of the view
    their keypoints put them (:func:`_image_side`); NaN rays leave them as they are."""
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
    return _image_side(out, directions, ray_a, ray_b, ok)


def _image_side(
    turned: FloatArray, before: FloatArray, ray_a: FloatArray, ray_b: FloatArray, ok: BoolArray
) -> FloatArray:
    """Unit ``turned`` directions (T, 3) that point back across the view, from the second
    ray toward the first, mirrored along the view onto the keypoints' side: a bone from a
    point on ray a to a point on ray b points along s_b·b̂ − s_a·â (depths s ≥ 0), so its
    component along e = b̂ − â is positive. The model's bone is often wrong that way where
    it points nearly along the view: its small part across the view is then the model's
    guess, the keypoints' direction is not (the stream on every third validation clip through
    the 12 views: right forearm 16.61° → 16.10°, the lifted performer 8.07° → 8.01°; the
    fold models on the pairs they never saw 14.13° → 13.94° and 18.63° → 18.24°; README,
    "Each bone on its keypoints' side"). A direction that would then be turned 90° or more
    from the model's (``before``) stays: the turns stay under 90° (:func:`_turns`), and a
    model that far off is not corrected by a reflection."""
    across = _unit(ray_b) - _unit(ray_a)
    size = np.linalg.norm(across, axis=-1, keepdims=True)
    ok = ok & (size[:, 0] > 1e-12)  # NaN sizes compare False
    across = np.where(ok[:, None], across / np.where(ok[:, None], size, 1.0), 0.0)
    side = np.sum(turned * across, axis=-1, keepdims=True)
    mirrored = turned - 2.0 * side * across
    flip = ok & (side[:, 0] < 0.0) & (np.sum(mirrored * before, axis=-1) > 0.0)
    return np.asarray(np.where(flip[:, None], mirrored, turned), dtype=np.float64)


def depth_from_length(
    directions: FloatArray,
    ray_a: FloatArray,
    ray_b: FloatArray,
    expected_px: FloatArray,
    depth_scale: float,
) -> FloatArray:
    """Unit bone ``directions`` (N, 3, camera frame) with their angle to the image plane moved
    toward the one their image length gives (the depth cue; :data:`DEPTH_SCALE`).

    A bone of image length ℓ whose full length across the view would be ``expected_px`` (N,)
    makes an angle φ = acos(ℓ / expected) with the plane across its viewing ray (the ray to
    its midpoint); the sign, toward or away from the camera, is the model's. The model's angle
    moves a share s² / (s² + ``depth_scale``²) of the way, s = sin φ: a length near the full
    one says little about the angle (its slope is s), a foreshortened one says much. Where
    an end point is missing or the expected length is not positive, the direction stays."""
    view = ray_a + ray_b
    view_len = np.linalg.norm(view, axis=-1, keepdims=True)
    image_len = np.linalg.norm(ray_b[:, :2] - ray_a[:, :2], axis=-1)
    ok = np.isfinite(view_len[:, 0]) & np.isfinite(image_len) & (expected_px > 0.0)
    view = np.where(ok[:, None], view / np.where(ok[:, None], view_len, 1.0), 0.0)
    sin_m = np.clip(np.sum(directions * view, axis=-1), -1.0, 1.0)
    across = directions - sin_m[:, None] * view
    across_len = np.linalg.norm(across, axis=-1, keepdims=True)
    ok &= across_len[:, 0] > 1e-9
    across = across / np.where(ok[:, None], across_len, 1.0)
    cos_i = np.clip(np.where(ok, image_len, 0.0) / np.where(ok, expected_px, 1.0), 0.0, 1.0)
    sin_i2 = 1.0 - cos_i**2
    share = sin_i2 / (sin_i2 + depth_scale**2)
    phi_m = np.arcsin(sin_m)
    phi_i = np.copysign(np.arccos(cos_i), sin_m)
    phi = phi_m + share * (phi_i - phi_m)
    moved = np.cos(phi)[:, None] * across + np.sin(phi)[:, None] * view
    return np.asarray(np.where(ok[:, None], moved, directions), dtype=np.float64)


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=np.float64)


def reproject(motion: HumanMotion, sequence: KeypointSequence) -> HumanMotion:
    """``motion`` (the keypoint model's answer for ``sequence``, frame for frame, heading frame)
    with its torso and limb bones turned toward the planes the image puts them in (module
    docstring); as it is where the keypoints cannot tell the camera
    (robot_retarget.keypoints.camera_fit)."""
    return reproject_with_camera(motion, sequence)[0]


def reproject_with_camera(
    motion: HumanMotion, sequence: KeypointSequence
) -> tuple[HumanMotion, CameraEstimate | None]:
    """:func:`reproject`, and the camera it fitted (None: none could be, the motion as it is)."""
    if motion.num_frames != sequence.num_frames:
        raise ValueError(f"motion has {motion.num_frames} frames, keypoints {sequence.num_frames}")
    xy = smooth_keypoints(sequence.xy, sequence.valid, sequence.fps)
    pose = MatrixPose.of(motion.skeleton, np.asarray(motion.local_quats))
    camera = fit_camera(pose.positions, motion.skeleton, xy)  # root at the origin
    if camera is None:
        return motion, None
    changes = plane_changes(pose, xy, camera, image_scale=frame_scales(pose.positions, xy, camera))
    # The turns carry what noise the smoothed keypoints still have; the model's error they
    # correct changes more slowly: they are smoothed again, over a longer time.
    changes = smooth_rotations(changes, motion.fps, CHANGE_SMOOTH_S)
    local = apply_changes(pose.local, changes)
    turned = HumanMotion(
        motion.skeleton, local, motion.root_pos, motion.fps, source_path=motion.source_path
    )
    return turned, camera


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
        t, j = local.shape[:2]
        local_m = matrices(local.reshape(t * j, 4)).reshape(t, j, 3, 3)
        # Pointer jumping, as the live networks' steps do: a few products for a whole frame.
        glob, positions = _kinematics(skeleton.parents).pose(local_m, skeleton.offsets)
        return cls(skeleton, local, glob, positions)


@functools.lru_cache(maxsize=8)
def _kinematics(parents: tuple[int, ...]) -> TreeKinematics:
    return TreeKinematics(parents)


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


def apply_changes(local: FloatArray, changes: FloatArray) -> FloatArray:
    """Local rotations (T, 22, 4) with :data:`CHANGED` joints' turned by ``changes``
    (T, len(CHANGED), 4), each applied on the left of its joint's local rotation."""
    out = np.array(local)
    turned = qmul(changes, out[:, CHANGED])
    out[:, CHANGED] = turned / np.linalg.norm(turned, axis=-1, keepdims=True)
    return out


def plane_changes(
    pose: MatrixPose,
    xy: FloatArray,
    camera: CameraEstimate,
    *,
    image_scale: FloatArray | None = None,
) -> FloatArray:
    """How ``pose`` (heading frame) turns with the torso and then each limb bone turned toward
    the planes of the keypoints ``xy`` (T, 17, 2) seen by ``camera`` (module docstring): the
    changes (T, len(CHANGED), 4, w > 0) of the :data:`CHANGED` joints' local rotations, for
    :func:`apply_changes` (the other joints' do not change). With the frames' ``image_scale``
    (T,) (pixels per metre at the hips' depth; NaN or ≤ 0: none that frame) the
    :data:`DEPTH_BONES` also take their angle to the image plane from their image length
    (:func:`depth_from_length`)."""
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
    upper = upper_body(pose.skeleton.parents)
    glob[:, upper] = _turns(before @ rot, after @ rot)[:, None] @ glob[:, upper]

    # Each limb bone on its own (its child keeps its global rotation), all in one pass.
    t, n = glob.shape[0], len(LIMB_BONES)
    bone = (glob[:, _LIMB_JOINTS] @ pose.skeleton.offsets[_LIMB_CHILDREN][..., None])[..., 0]
    before = (_unit(bone) @ rot.T).reshape(t * n, 3)
    ray_a = camera.rays(xy[:, _LIMB_KEY_STARTS]).reshape(t * n, 3)
    ray_b = camera.rays(xy[:, _LIMB_KEY_ENDS]).reshape(t * n, 3)
    after = _into_planes(before, ray_a, ray_b)
    if image_scale is not None:
        after = _with_depth(after, ray_a, ray_b, pose, rot, camera.distance_m, image_scale)
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


def _with_depth(
    after: FloatArray,
    ray_a: FloatArray,
    ray_b: FloatArray,
    pose: MatrixPose,
    rot: FloatArray,
    distance: float,
    image_scale: FloatArray,
) -> FloatArray:
    """The limb bones' turned directions (T·8, 3) with :func:`depth_from_length` on the
    :data:`DEPTH_BONES`: each bone's full image length is the frame's image scale × its
    length on the skeleton, at its midpoint's depth in the model's pose."""
    t, n = pose.positions.shape[0], len(LIMB_BONES)
    mid = 0.5 * (pose.positions[:, _LIMB_JOINTS] + pose.positions[:, _LIMB_CHILDREN])
    depth_off = (mid @ rot.T)[..., 2]  # along the view, from the hips (T, 8)
    lengths = np.linalg.norm(pose.skeleton.offsets[_LIMB_CHILDREN], axis=-1)
    scale = np.asarray(image_scale, dtype=np.float64).reshape(t, 1)
    scale = np.where(np.isfinite(scale) & (scale > 0.0), scale, 0.0)
    expected = (scale * lengths / (1.0 + depth_off / distance)).reshape(t * n)
    moved = depth_from_length(after, ray_a, ray_b, expected, DEPTH_SCALE)
    on = np.tile(DEPTH_BONES, t)
    return np.asarray(np.where(on[:, None], moved, after), dtype=np.float64)


def upper_body(parents: tuple[int, ...]) -> list[int]:
    """The joints the torso's turn moves: the spine's first joint and everything below it."""
    return _subtree(parents, int(Joint.Spine))


def _subtree(parents: tuple[int, ...], root: int) -> list[int]:
    """``root`` and every joint below it (parents come first)."""
    inside = {root}
    for j, p in enumerate(parents):
        if p in inside:
            inside.add(j)
    return sorted(inside)
