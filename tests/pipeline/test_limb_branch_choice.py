"""convert chooses each limb's branch on the whole clip: CMU 12_01's first frames (the DAZ
rest pose, arms out) once held OP3's left arm horizontal for the whole walk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.evaluation.robot.metrics import segment_angles
from robot_retarget.evaluation.robot.segments import SEGMENTS, RobotBodyModel, human_body_points
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.pipeline.convert import convert_motion
from robot_retarget.pipeline.defaults import default_model_name
from robot_retarget.pipeline.limb_branch_choice import limb_segments
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.skeleton.canonical import default_canonical_skeleton


def test_each_arm_and_leg_scores_its_own_segments() -> None:
    op3 = load_robot_config("op3")
    step = RetargetStep(op3, default_model_name(), default_canonical_skeleton())
    names = [
        sorted(SEGMENTS[i] for i in segs)
        for segs in limb_segments(RobotBodyModel(op3), step.retargeter.limbs)
    ]
    assert ["left_forearm", "left_upper_arm"] in names
    assert ["right_forearm", "right_upper_arm"] in names
    assert all("torso" not in n for n in names)


@pytest.mark.data
def test_op3_left_arm_follows_the_daz_walk(shared_data_dir: Path) -> None:
    op3 = load_robot_config("op3")
    motion = load_motion(shared_data_dir / "mocap" / "12" / "12_01.bvh")
    step = RetargetStep(op3, default_model_name(), motion.skeleton)
    body = RobotBodyModel(op3)
    left_arm = SEGMENTS.index("left_upper_arm")
    errors = {}
    for whole_clip in (False, True):
        traj = convert_motion(motion, step, whole_clip_branches=whole_clip).trajectory
        idx = np.arange(0, traj.num_frames, 12)
        human = human_body_points(motion.resample(traj.fps).positions()[idx])
        angles = segment_angles(human, body.body_points(np.asarray(traj.q)[idx]))
        errors[whole_clip] = float(np.degrees(np.median(angles[:, left_arm])))
    assert errors[False] > 60.0  # the first frame's branch: horizontal, as stream keeps it
    assert errors[True] < 30.0  # 21.6°, as the right arm, never trapped (20.7°)


def test_a_failed_conversion_leaves_no_branch_choice_behind() -> None:
    """The choice lives for one clip: an exception mid-clip (here from the progress callback)
    must not hand it to the next clip or to a stream on the same step."""
    from robot_retarget.motion.synthetic import demo_motion

    op3 = load_robot_config("op3")
    motion = demo_motion(fps=30.0).frames(0, 30)
    step = RetargetStep(op3, default_model_name(), motion.skeleton)

    def fail(done: int, total: int) -> None:
        if done == 3:
            raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        convert_motion(motion, step, whole_clip_branches=True, progress=fail)
    assert step.settle_branches is None


def test_the_progress_covers_the_branch_choice() -> None:
    from robot_retarget.motion.synthetic import demo_motion

    op3 = load_robot_config("op3")
    motion = demo_motion(fps=30.0).frames(0, 20)
    step = RetargetStep(op3, default_model_name(), motion.skeleton)
    calls: list[tuple[int, int]] = []
    traj = convert_motion(
        motion, step, whole_clip_branches=True, progress=lambda d, t: calls.append((d, t))
    ).trajectory
    n = traj.num_frames
    assert calls[-1] == (4 * n, 4 * n)  # three runs to choose, then the conversion
    assert [d for d, _ in calls] == list(range(1, 4 * n + 1))
