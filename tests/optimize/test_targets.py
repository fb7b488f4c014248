"""Canonical rotations → optimizer targets in a heading-free body frame."""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.errors import SolveError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.optimize.formulation import RobotProblem
from robot_retarget.optimize.targets import (
    ClipTargets,
    FrameTargetBuilder,
    targets_from_globals,
    targets_from_rotations,
)
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.skeleton.canonical import Joint, default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics


@pytest.fixture(scope="module")
def problem(op3: RobotConfig) -> RobotProblem:
    return RobotProblem(op3)


@cache
def _op3_problem() -> RobotProblem:  # cached: hypothesis examples share one
    return RobotProblem(load_robot_config("op3"))


def _rest(frames: int = 1) -> np.ndarray:
    return quat.identity((frames, 22))


def test_rest_pose_gives_rest_axes_and_normals(problem: RobotProblem) -> None:
    tg = targets_from_rotations(problem, default_canonical_skeleton(), _rest())
    np.testing.assert_allclose(tg.directions[0], [b.rest_axis for b in problem.bones], atol=1e-12)
    np.testing.assert_allclose(tg.normals[0], [b.rest_normal for b in problem.bones], atol=1e-12)


def test_left_arm_raised_forward_points_along_robot_forward(problem: RobotProblem) -> None:
    q = _rest()
    q[0, Joint.LeftArm] = quat.from_axis_angle([0.0, 1.0, 0.0], -math.pi / 2)
    tg = targets_from_rotations(problem, default_canonical_skeleton(), q)
    k = [b.canonical for b in problem.bones].index("LeftArm")
    np.testing.assert_allclose(tg.directions[0, k], [1.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("yaw_deg", [-170.0, -30.0, 45.0, 120.0])
def test_targets_do_not_depend_on_heading(problem: RobotProblem, yaw_deg: float) -> None:
    rng = np.random.default_rng(5)
    q = quat.normalize(quat.identity((3, 22)) + 0.3 * rng.normal(size=(3, 22, 4)))
    turned = q.copy()
    yaw = quat.from_axis_angle([0.0, 1.0, 0.0], math.radians(yaw_deg))
    turned[:, Joint.Hips] = quat.mul(yaw, q[:, Joint.Hips])
    sk = default_canonical_skeleton()
    a = targets_from_rotations(problem, sk, q, end_effectors=True)
    b = targets_from_rotations(problem, sk, turned, end_effectors=True)
    np.testing.assert_allclose(a.directions, b.directions, atol=1e-9)
    np.testing.assert_allclose(a.normals, b.normals, atol=1e-9)
    np.testing.assert_allclose(a.ee_positions, b.ee_positions, atol=1e-9)


def test_end_effectors_are_relative_to_the_hips_and_scaled(problem: RobotProblem) -> None:
    sk = default_canonical_skeleton()
    tg = targets_from_rotations(
        problem, sk, _rest(), root_pos=np.array([[5.0, 1.0, -2.0]]), end_effectors=True, scale=0.5
    )
    rest = sk.rest_positions()
    hips = 0.5 * (rest[Joint.LeftUpLeg] + rest[Joint.RightUpLeg])
    k = [name for name, _ in problem.ee_frames].index("LeftHand")
    want = problem.hip_center + problem.canonical_to_root @ ((rest[Joint.LeftHand] - hips) * 0.5)
    np.testing.assert_allclose(tg.ee_positions[0, k], want, atol=1e-12)


def test_invalid_input_raises(problem: RobotProblem) -> None:
    q = _rest(2)
    q[1, 3, 0] = math.nan
    with pytest.raises(SolveError, match="NaN"):
        targets_from_rotations(problem, default_canonical_skeleton(), q)
    small = Skeleton(("Hips", "Spine"), (-1, 0), np.zeros((2, 3)))
    with pytest.raises(SolveError, match="canonical skeleton"):
        targets_from_rotations(problem, small, _rest())
    with pytest.raises(SolveError, match=r"\(T, 22, 4\)"):
        targets_from_rotations(problem, default_canonical_skeleton(), quat.identity((22,)))


def test_clip_targets_frame_and_slice() -> None:
    dirs = np.arange(4 * 2 * 3, dtype=float).reshape(4, 2, 3)
    clip = ClipTargets(dirs, root_height_m=np.array([0.1, 0.2, 0.3, 0.4]))
    assert len(clip) == 4
    assert len(clip.slice(1, 3)) == 2
    f = clip.frame(2)
    np.testing.assert_array_equal(f.directions, dirs[2])
    assert f.root_height_m == pytest.approx(0.3)
    assert f.normals is None
    assert f.ee_positions is None


def test_globals_path_matches_rotations_path(problem: RobotProblem) -> None:
    rng = np.random.default_rng(9)
    q = quat.normalize(quat.identity((4, 22)) + 0.4 * rng.normal(size=(4, 22, 4)))
    sk = default_canonical_skeleton()
    pos, glob = forward_kinematics(sk, q)
    a = targets_from_rotations(problem, sk, q, end_effectors=True)
    b = targets_from_globals(problem, pos, glob, end_effectors=True)
    np.testing.assert_array_equal(a.directions, b.directions)
    np.testing.assert_array_equal(a.normals, b.normals)
    np.testing.assert_array_equal(a.ee_positions, b.ee_positions)
    with pytest.raises(SolveError, match="positions"):
        targets_from_globals(problem, pos[0], glob)


# --------------------------------------------------------------- FrameTargetBuilder (live path)
def _assert_same_targets(
    problem: RobotProblem,
    skeleton: Skeleton,
    local_quats: np.ndarray,
    *,
    end_effectors: bool = False,
    scale: float = 1.0,
) -> None:
    """The per-frame builder equals targets_from_rotations frame by frame (to 1e-12)."""
    ref = targets_from_rotations(
        problem,
        skeleton,
        local_quats,
        root_pos=np.full((len(local_quats), 3), 3.0),
        end_effectors=end_effectors,
        scale=scale,
    )
    build = FrameTargetBuilder(problem, skeleton, end_effectors=end_effectors, scale=scale)
    for t in range(len(local_quats)):
        got, want = build(local_quats[t]), ref.frame(t)
        np.testing.assert_allclose(got.directions, want.directions, rtol=0, atol=1e-12)
        assert want.normals is not None
        assert got.normals is not None
        np.testing.assert_allclose(got.normals, want.normals, rtol=0, atol=1e-12)
        if want.ee_positions is None:
            assert got.ee_positions is None
        else:
            assert got.ee_positions is not None
            np.testing.assert_allclose(got.ee_positions, want.ee_positions, rtol=0, atol=1e-12)
        assert got.ee_weights is None
        assert got.root_height_m is None


@pytest.mark.parametrize("robot", ["op3", "poppy"])
@pytest.mark.parametrize("end_effectors", [False, True])
def test_frame_builder_equals_clip_targets_on_the_demo(
    robot: str, end_effectors: bool, request: pytest.FixtureRequest
) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    skeleton = robot_canonical_skeleton(config)
    quats = demo_motion(fps=10.0).local_quats
    _assert_same_targets(
        RobotProblem(config), skeleton, quats, end_effectors=end_effectors, scale=0.8
    )


@settings(max_examples=25, deadline=None)
@given(arrays(np.float64, (4, 22, 3), elements=st.floats(-3.0, 3.0)))
def test_frame_builder_equals_clip_targets_on_wild_poses(rotvecs: np.ndarray) -> None:
    problem = _op3_problem()
    _assert_same_targets(
        problem,
        default_canonical_skeleton(),
        quat.from_rotation_vector(rotvecs),
        end_effectors=True,
    )


def test_frame_builder_falls_back_like_the_clip_path(problem: RobotProblem) -> None:
    """Hips axis vertical (no heading) and a zero-length bone: the same fallbacks."""
    q = _rest(2)
    q[0, Joint.Hips] = quat.from_axis_angle([0.0, 0.0, 1.0], math.pi / 2)
    offsets = default_canonical_skeleton().offsets.copy()
    offsets[Joint.LeftForeArm] = 0.0  # the upper arm (LeftArm → LeftForeArm) has no length
    skeleton = default_canonical_skeleton().with_offsets(offsets)
    _assert_same_targets(problem, skeleton, q)


@pytest.mark.data
def test_frame_builder_equals_clip_targets_on_real_mocap(
    problem: RobotProblem, op3: RobotConfig, shared_data_dir: Path
) -> None:
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh", max_frames=240)
    _assert_same_targets(problem, robot_canonical_skeleton(op3), motion.local_quats[::4])
    _assert_same_targets(problem, motion.skeleton, motion.local_quats[::4], end_effectors=True)


def test_frame_builder_rejects_bad_input(problem: RobotProblem) -> None:
    build = FrameTargetBuilder(problem, default_canonical_skeleton())
    q = _rest()[0]
    q[3, 1] = np.nan
    with pytest.raises(SolveError, match="NaN"):
        build(q)
    with pytest.raises(SolveError, match="shape"):
        build(_rest()[0, :21])
    bad = Skeleton(("a", "b"), (-1, 0), np.zeros((2, 3)))
    with pytest.raises(SolveError, match="canonical skeleton"):
        FrameTargetBuilder(problem, bad)


@pytest.mark.parametrize("robot", ["op3", "poppy"])
def test_the_trunk_bone_follows_the_torso_line_not_the_neck_joint(
    robot: str, request: pytest.FixtureRequest
) -> None:
    """A rig whose Hips joint sits behind the hip midpoint (as the CMU conversions' do, by
    10-11°) leans its Hips → Neck line; the trunk bone's target is still the torso line, which
    in the trunk frame is the robot's up, in every frame and both paths."""
    config: RobotConfig = request.getfixturevalue(robot)
    problem = RobotProblem(config)
    offsets = default_canonical_skeleton().offsets.copy()
    offsets[Joint.Spine] += [0.0, 0.0, -0.06]  # the spine starts 6 cm behind the hips
    skeleton = default_canonical_skeleton().with_offsets(offsets)
    rng = np.random.default_rng(3)
    q = quat.from_rotation_vector(rng.normal(0.0, 0.4, (5, 22, 3)))
    k = [b.canonical for b in problem.bones].index("Hips")
    up = np.asarray(config.up_axis, dtype=np.float64)
    clip = targets_from_rotations(problem, skeleton, q)
    np.testing.assert_allclose(clip.directions[:, k], np.tile(up, (5, 1)), atol=1e-12)
    build = FrameTargetBuilder(problem, skeleton)
    for t in range(5):
        np.testing.assert_allclose(build(q[t]).directions[k], up, atol=1e-12)
    # The Hips → Neck joints themselves lean off that line in the trunk frame.
    pos, _ = forward_kinematics(skeleton, q, None)
    neck = pos[:, Joint.Neck] - pos[:, Joint.Hips]
    torso = 0.5 * (pos[:, Joint.LeftArm] + pos[:, Joint.RightArm] - pos[:, Joint.LeftUpLeg]
                   - pos[:, Joint.RightUpLeg])  # fmt: skip
    cos = (
        np.sum(neck * torso, axis=1) / np.linalg.norm(neck, axis=1) / np.linalg.norm(torso, axis=1)
    )
    assert np.degrees(np.arccos(cos)).min() > 3.0


@settings(max_examples=25, deadline=None)
@given(arrays(np.float64, (3, 22, 3), elements=st.floats(-3.0, 3.0)))
def test_normal_targets_are_perpendicular_to_direction_targets(rotvecs: np.ndarray) -> None:
    """On the robot's own skeleton a bone's roll target stands at right angles to its direction
    target, as the robot's normal does to its bone: OP3's foot (ankle → toe 4.65° steeper than
    the canonical foot) once had a roll target 4.65° off, and the two terms pulled the foot
    between them."""
    problem = _op3_problem()
    skeleton = robot_canonical_skeleton(problem.config)
    quats = quat.from_rotation_vector(rotvecs)
    clip = targets_from_rotations(problem, skeleton, quats)
    builder = FrameTargetBuilder(problem, skeleton)
    assert clip.normals is not None
    direct = [k for k, b in enumerate(problem.bones) if b.canonical != "Hips"]
    for t in range(len(quats)):
        frame = builder(quats[t])
        assert frame.normals is not None
        for dirs, normals in (
            (clip.directions[t], clip.normals[t]),
            (frame.directions, frame.normals),
        ):
            dots = np.einsum("bi,bi->b", dirs[direct], normals[direct])
            np.testing.assert_allclose(dots, 0.0, atol=1e-9)


def test_rest_targets_are_the_robots_zero_pose_on_its_own_skeleton() -> None:
    """Identity rotations on the robot's skeleton: each limb bone's direction and normal targets
    are the robot's own at its zero pose (up to the trunk frame's own tilt there)."""
    problem = _op3_problem()
    tg = FrameTargetBuilder(problem, robot_canonical_skeleton(problem.config))(_rest()[0])
    zero = np.zeros(problem.num_joints)
    dirs = np.asarray(problem.directions_function(zero)).T
    normals = np.asarray(problem.normals_function(zero)).T
    assert tg.normals is not None
    limbs = [k for k, b in enumerate(problem.bones) if b.canonical not in ("Hips", "Neck")]
    for got, want in ((tg.directions, dirs), (tg.normals, normals)):
        angles = np.degrees(np.arccos(np.clip(np.einsum("bi,bi->b", got, want), -1.0, 1.0)))
        assert np.all(angles[limbs] < 0.1), angles
