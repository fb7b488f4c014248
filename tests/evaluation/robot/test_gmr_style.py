"""The GMR-style baseline: its targets, its IK, its limits."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

from robot_retarget.evaluation.robot.gmr_style import GMRStyleIK, GMRStyleSettings, GMRTargets
from robot_retarget.evaluation.robot.metrics import segment_angles, trajectory_stats
from robot_retarget.evaluation.robot.segments import RobotBodyModel, human_body_points
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.optimize.formulation import RobotProblem
from robot_retarget.optimize.targets import targets_from_globals
from robot_retarget.pipeline.floating_base import base_rotations
from robot_retarget.robot.config import RobotConfig
from robot_retarget.skeleton.trunk import trunk_frames_of_positions

FloatArray = npt.NDArray[np.float64]


def test_a_robot_shaped_human_is_reproduced(
    op3: RobotConfig, op3_body: RobotBodyModel, poses: FloatArray, human_for
) -> None:  # type: ignore[no-untyped-def]
    # The position tasks alone (no foot orientation, posture or damping): every limb point is
    # reachable, so the IK reproduces the robot's own pose.
    alone = GMRStyleSettings(orientation_cost=0.0, posture_cost=0.0, damping=1e-9)
    ik = GMRStyleIK(op3, op3_body.frames, alone)
    pos = human_for(poses, yaw_rad=0.7)
    identity = np.zeros((*pos.shape[:2], 4))
    identity[..., 0] = 1.0
    result = ik.solve_clip(ik.targets(pos, identity), 1.0 / 125.0, q_start=poses[0])
    # Targets are in the performer's trunk frame: the robot stands on the base that follows it.
    world = base_rotations(op3, trunk_frames_of_positions(pos))
    robot = op3_body.body_points(result.q, world)
    angles = np.degrees(segment_angles(human_body_points(pos), robot))
    # Where the sweep outruns the servos (1.4 × an arm's speed limit) the IK lags; else exact.
    assert float(np.median(angles[:, :8])) < 1e-6
    assert angles[:, :8].mean() < 1.0


def test_foot_targets_agree_with_the_optimizer_bone_targets(
    op3: RobotConfig, op3_body: RobotBodyModel
) -> None:
    # The foot link's target rotation, carried through the foot bone's alignment, must point
    # the bone where the optimizer's direction and normal targets point it.
    motion = demo_motion(fps=125.0).frames(0, 40)
    pos, glob = motion.positions(), motion.global_quats()
    ik = GMRStyleIK(op3, op3_body.frames)
    tg = ik.targets(pos, glob)
    problem = RobotProblem(op3)
    bones = {b.canonical: k for k, b in enumerate(problem.bones)}
    opt = targets_from_globals(problem, pos, glob)
    assert opt.normals is not None
    for f, name in enumerate(("LeftFoot", "RightFoot")):
        k = bones[name]
        bone = problem.bones[k]
        g = tg.rotations[:, f] @ problem.alignments[k]  # G_robot = R_link · C
        np.testing.assert_allclose(g @ bone.rest_axis, opt.directions[:, k], atol=1e-9)
        np.testing.assert_allclose(g @ bone.rest_normal, opt.normals[:, k], atol=1e-9)


def test_limits_and_speeds_hold(op3: RobotConfig, op3_body: RobotBodyModel) -> None:
    motion = demo_motion(fps=125.0).frames(0, 150)
    ik = GMRStyleIK(op3, op3_body.frames)
    result = ik.solve_clip(ik.targets(motion.positions(), motion.global_quats()), 1.0 / 125.0)
    stats = trajectory_stats(op3, result.q, 125.0)
    assert stats.limit_violations == 0
    assert stats.speed_violations == 0


def test_targets_check_their_shapes(op3: RobotConfig, op3_body: RobotBodyModel) -> None:
    ik = GMRStyleIK(op3, op3_body.frames)
    with pytest.raises(Exception, match="must match"):
        ik.targets(np.zeros((3, 22, 3)), np.zeros((2, 22, 4)))
    pos = np.zeros((1, 22, 3)) + np.arange(22)[None, :, None] * 0.01
    assert isinstance(ik.targets(pos, np.tile([1.0, 0.0, 0.0, 0.0], (1, 22, 1))), GMRTargets)
