"""Each limb's branch chosen on the whole clip, for ``convert`` (which sees the whole clip).

A warm-started sequence keeps the branch each limb settles in on the first frame
(robot_retarget.optimize.limb_branches), and on OP3's 3-joint arms the first frame's best
branch is a coin toss for the rest of the clip: the DAZ conversions start in a rest pose with
the arms straight out, where two optima differ in cost by 0.015, and on CMU 12_01 the one taken
holds the left arm horizontal for the whole walk, 83° off the performer's hanging arm.

:func:`choose_branches` runs the clip once per start of the first frame's multi-start (each
limb from its current optimum, its joints at zero, its joints negated), scores each limb's
segments against the performer's over the clip (the eval-robot segments, at 10 frames per
second), and returns per limb the start whose run followed the performer best. ``stream``
cannot see ahead and keeps the first frame's best.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.evaluation.robot.metrics import segment_angles
from robot_retarget.evaluation.robot.segments import RobotBodyModel, human_body_points
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.optimize.limb_branches import LimbBranches
from robot_retarget.pipeline.step import RetargetStep

STARTS = LimbBranches.NUM_STARTS  # the current optimum, the joints at zero, negated
_SCORE_FPS = 10.0
_PROBE_RAD = 0.3


def limb_segments(body: RobotBodyModel, limbs: tuple[IntArray, ...]) -> list[IntArray]:
    """Per limb, the scored segments its joints move (the torso excluded)."""
    q0 = np.asarray(body.config.init_pose, dtype=np.float64)
    base = body.body_points(q0[None]).directions[0]
    out = []
    for joints in limbs:
        moved = q0.copy()
        moved[joints] += _PROBE_RAD
        turned = np.linalg.norm(body.body_points(moved[None]).directions[0] - base, axis=-1)
        out.append(np.flatnonzero(turned[:-1] > 1e-6))  # the last segment is the torso
    return out


def run_clip(
    motion: HumanMotion,
    step: RetargetStep,
    dt: float,
    progress: Callable[[int], None] | None = None,
) -> FloatArray:
    """Joint angles of every frame, frame by frame as convert runs them (no safety layer:
    only the choice is made from them); ``progress`` gets the frames done."""
    step.reset(step.config.init_pose)
    q = np.empty((motion.num_frames, step.config.num_joints))
    for t in range(motion.num_frames):
        q[t] = step(motion.local_quats[t], motion.root_pos[t], dt, settle=t == 0).q
        if progress is not None:
            progress(t + 1)
    return q


def choose_branches(
    motion: HumanMotion,
    step: RetargetStep,
    dt: float,
    progress: Callable[[int], None] | None = None,
) -> tuple[int | None, ...] | None:
    """Per limb, the first-frame start whose run follows the performer best (None: no limb
    has a choice to make); ``progress`` gets the frames done over the :data:`STARTS` runs."""
    limbs = step.retargeter.limbs
    if not limbs or motion.num_frames < 2:
        return None
    body = RobotBodyModel(step.config)
    segments = limb_segments(body, limbs)
    stride = max(1, round(1.0 / (dt * _SCORE_FPS)))
    idx = np.arange(0, motion.num_frames, stride)
    human = human_body_points(motion.positions()[idx])
    scores = np.empty((STARTS, len(limbs)))
    saved = step.settle_branches
    try:
        for k in range(STARTS):
            step.settle_branches = (k,) * len(limbs)
            done = k * motion.num_frames
            tick = None if progress is None else (lambda t, done=done: progress(done + t))
            q = run_clip(motion, step, dt, tick)
            angles = segment_angles(human, body.body_points(q[idx]))
            for i, segs in enumerate(segments):
                scores[k, i] = float(angles[:, segs].mean()) if segs.size else 0.0
    finally:
        step.settle_branches = saved
    return tuple(
        int(np.argmin(scores[:, i])) if segments[i].size else None for i in range(len(limbs))
    )
