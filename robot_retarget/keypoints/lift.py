"""Keypoints → a canonical HumanMotion through the keypoint model, for ``convert`` and the API.

The model gives rotations only: from one uncalibrated camera the performer's path across the
room is not recovered, so the root stays over the origin at the reference skeleton's standing
hip height (the robot steps in place; its pose and heading follow the performer). Its heading
is relative to the camera: a performer facing the camera faces the robot's forward.

Points no body could have produced (an estimator's glitch: robot_retarget.keypoints.
glitch_gate) are marked missing first, as ``stream`` does frame by frame, and counted.

A frame in which fewer than :data:`MIN_BODY_POINTS` of the 12 body points (shoulders to
ankles) are seen — nobody followed in view, or an occluded body — gets no pose of its own: the
last seen frame's pose is held (the first seen one before it), and the count is reported
(:class:`LiftedKeypoints`), never filled in silently.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from robot_retarget.array_types import BoolArray
from robot_retarget.errors import MotionFormatError
from robot_retarget.keypoints.camera_fit import CameraEstimate
from robot_retarget.keypoints.coco17 import BODY_JOINTS
from robot_retarget.keypoints.glitch_gate import gate_keypoints
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton


def standing_root(skeleton: Skeleton) -> np.ndarray:
    """The Hips position (3,) of ``skeleton`` standing on y = 0 in its rest pose."""
    rest = skeleton.rest_positions()
    return np.array([0.0, -float(rest[:, 1].min()), 0.0])


MIN_BODY_POINTS = 6
_BODY = np.array(sorted(BODY_JOINTS), dtype=np.int64)


def body_seen(sequence: KeypointSequence) -> BoolArray:
    """(T,) frames with at least MIN_BODY_POINTS body points seen."""
    seen: BoolArray = sequence.valid[:, _BODY].sum(axis=1) >= MIN_BODY_POINTS
    return seen


@dataclass(frozen=True)
class LiftedKeypoints:
    """A lifted keypoint file: the motion and what was missing in it."""

    motion: HumanMotion
    frames_held: int  # frames without enough body points: the last seen pose held
    missing_fraction: float  # share of all points marked missing
    camera: CameraEstimate | None  # fitted for the image's planes (None: off, or no fit)
    refused_points: int = 0  # points the glitch gate marked missing


def lift_keypoints(
    sequence: KeypointSequence,
    model: Agnostic2DRuntime,
    *,
    causal: bool = False,
    image_planes: bool = True,
) -> HumanMotion:
    """The performer's motion on the reference skeleton, averaged with the mirrored image's
    answer (``causal=False``: the whole clip's static codes, as ``convert`` uses; ``True``: as
    ``stream``'s step computes it frame by frame). ``image_planes`` (default on): the torso
    and limb bones turned into the planes the keypoints put them in, with the camera fitted on
    the whole clip (robot_retarget.keypoints.reprojection) or, when causal, on the frames so
    far as ``stream`` does (robot_retarget.keypoints.online_reprojection)."""
    return _lift(sequence, model, causal=causal, image_planes=image_planes)[0]


def without_glitches(sequence: KeypointSequence) -> tuple[KeypointSequence, int]:
    """``sequence`` with the glitch gate's refused points marked missing, and their count."""
    valid, refused = gate_keypoints(sequence.xy, sequence.valid, sequence.fps)
    if not refused:
        return sequence, 0
    xy = np.where(valid[..., None], sequence.xy, np.nan)
    return replace(sequence, xy=xy, valid=valid), refused


def _lift(
    sequence: KeypointSequence, model: Agnostic2DRuntime, *, causal: bool, image_planes: bool
) -> tuple[HumanMotion, CameraEstimate | None, int, int]:
    """:func:`lift_keypoints`, the camera the image's planes used (the last one, causal), the
    number of points the glitch gate refused and of frames without a body after it."""
    sequence, refused = without_glitches(sequence)
    skeleton = default_canonical_skeleton()
    # Averaged with the mirrored image's answer, as the live step does (Agnostic2DRuntime.online).
    quats = model.run_clip(sequence.xy, sequence.valid, causal=causal, mirror_average=True)
    root = np.repeat(standing_root(skeleton)[None], sequence.num_frames, axis=0)
    seen = body_seen(sequence)
    if not seen.any():
        raise MotionFormatError(
            f"no frame shows {MIN_BODY_POINTS} or more body points above the confidence "
            "threshold: nobody to follow (check the estimator's output, or lower its threshold)",
            path=sequence.source or None,
        )
    camera = None
    if image_planes and causal:
        from robot_retarget.keypoints.online_reprojection import OnlineReprojection

        planes = OnlineReprojection(skeleton, fps=sequence.fps, image_size=sequence.image_size)
        quats = np.stack([planes.step(q, xy) for q, xy in zip(quats, sequence.xy, strict=True)])
        camera = planes.camera
    elif image_planes:
        from robot_retarget.keypoints.reprojection import reproject_with_camera

        motion = HumanMotion(skeleton, quats, root, sequence.fps, source_path=sequence.source)
        turned, camera = reproject_with_camera(motion, sequence)
        quats = np.asarray(turned.local_quats)
    # Frames without a body hold the last seen pose (the first seen one before it).
    last = np.maximum.accumulate(np.where(seen, np.arange(len(seen)), -1))
    last[last < 0] = int(np.argmax(seen))
    lifted = HumanMotion(skeleton, quats[last], root, sequence.fps, source_path=sequence.source)
    return lifted, camera, refused, int((~seen).sum())


def load_keypoint_motion(
    path: Path,
    *,
    model: str | None = None,
    fps: float | None = None,
    max_frames: int | None = None,
    image_planes: bool = True,
) -> LiftedKeypoints:
    """A keypoint file or folder (robot_retarget.sources.keypoints) lifted by the keypoint
    model (None: the shipped one for whole clips, which looks ahead), non-causally, as
    ``convert`` does (``image_planes``: see :func:`lift_keypoints`)."""
    from robot_retarget.runtime.agnostic2d import load_keypoint_model
    from robot_retarget.sources.keypoints import load_keypoints

    seq = load_keypoints(path, fps=fps)
    if max_frames is not None:
        seq = KeypointSequence(
            seq.xy[:max_frames], seq.confidence[:max_frames], seq.valid[:max_frames], seq.fps,
            seq.source,
        )  # fmt: skip
    motion, camera, refused, held = _lift(
        seq, load_keypoint_model(model, whole_clip=True), causal=False, image_planes=image_planes
    )
    return LiftedKeypoints(motion, held, seq.missing_fraction, camera, refused)
