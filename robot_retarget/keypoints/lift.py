"""Keypoints → a canonical HumanMotion through the keypoint model, for ``convert`` and the API.

The model gives rotations only: from one uncalibrated camera the performer's path across the
room is not recovered, so the root stays over the origin at the reference skeleton's standing
hip height (the robot steps in place; its pose and heading follow the performer). Its heading
is relative to the camera: a performer facing the camera faces the robot's forward.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton


def standing_root(skeleton: Skeleton) -> np.ndarray:
    """The Hips position (3,) of ``skeleton`` standing on y = 0 in its rest pose."""
    rest = skeleton.rest_positions()
    return np.array([0.0, -float(rest[:, 1].min()), 0.0])


def lift_keypoints(
    sequence: KeypointSequence, model: Agnostic2DRuntime, *, causal: bool = False
) -> HumanMotion:
    """The performer's motion on the reference skeleton (``causal=False``: the whole clip's
    static codes and the mirrored image's answer averaged in, as ``convert`` uses)."""
    skeleton = default_canonical_skeleton()
    # The whole clip is at hand offline: average with the mirrored image's answer too.
    quats = model.run_clip(sequence.xy, sequence.valid, causal=causal, mirror_average=not causal)
    root = np.repeat(standing_root(skeleton)[None], sequence.num_frames, axis=0)
    return HumanMotion(skeleton, quats, root, sequence.fps, source_path=sequence.source)


def load_keypoint_motion(
    path: Path,
    *,
    model: str | None = None,
    fps: float | None = None,
    max_frames: int | None = None,
) -> HumanMotion:
    """A keypoint file or folder (robot_retarget.sources.keypoints) lifted by the keypoint
    model (None: the shipped one), non-causally, as ``convert`` does."""
    from robot_retarget.runtime.agnostic2d import load_keypoint_model
    from robot_retarget.sources.keypoints import load_keypoints

    seq = load_keypoints(path, fps=fps)
    if max_frames is not None:
        seq = KeypointSequence(
            seq.xy[:max_frames], seq.confidence[:max_frames], seq.valid[:max_frames], seq.fps,
            seq.source,
        )  # fmt: skip
    return lift_keypoints(seq, load_keypoint_model(model), causal=False)
