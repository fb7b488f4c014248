from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import check_limits, convert_motion, output_paths
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig


def test_convert_is_within_limits_and_complete(step: RetargetStep, demo: HumanMotion,
                                               op3: RobotConfig) -> None:  # fmt: skip
    calls: list[int] = []
    result = convert_motion(demo, step, fps=50.0, progress=lambda d, t: calls.append(d))
    traj = result.trajectory
    assert traj.fps == 50.0
    assert traj.num_frames == 101  # 2 s at 50 fps, both ends included
    assert traj.joint_names == op3.joint_names
    assert traj.root_pos is not None
    assert traj.root_quat is not None
    assert traj.frame_ms is not None
    assert traj.t0 == 0.0
    assert result.limits.ok
    assert check_limits(op3, traj.q, 1 / 50).ok
    assert result.safety_commands_clipped == 0
    assert result.fallbacks == 0
    assert calls[-1] == traj.num_frames


def test_default_rate_is_the_control_rate(step: RetargetStep, demo: HumanMotion,
                                          op3: RobotConfig) -> None:  # fmt: skip
    result = convert_motion(demo.frames(0, 10), step)
    assert result.trajectory.fps == op3.control_rate_hz


def test_same_input_gives_the_same_trajectory(step: RetargetStep, demo: HumanMotion) -> None:
    a = convert_motion(demo, step, fps=30.0).trajectory.q
    b = convert_motion(demo, step, fps=30.0).trajectory.q
    np.testing.assert_array_equal(a, b)


def test_the_file_starts_at_the_first_frame_not_at_the_init_pose(
    step: RetargetStep, demo: HumanMotion, op3: RobotConfig
) -> None:
    """No catching up from the init crouch: frame 0 is solved to its optimum, so a one-frame
    clip is that pose and the first steps of a longer one move at the motion's speed."""
    q = convert_motion(demo, step, fps=30.0).trajectory.q
    one = convert_motion(demo.frames(0, 1), step, fps=30.0).trajectory.q
    np.testing.assert_array_equal(one[0], q[0])
    assert float(np.max(np.abs(q[0] - op3.init_pose))) > 1.0  # the demo's arms are not crouched
    first_step = np.abs(q[1] - q[0]) / (op3.max_velocity / 30.0)
    assert float(first_step.max()) < 0.5  # catching up would be 1.0 (the velocity limit)


def test_check_limits_counts_steps_from_the_start_pose_when_given(op3: RobotConfig) -> None:
    q = np.tile(op3.upper, (2, 1))
    assert check_limits(op3, q, 0.01).ok  # a file that starts where it starts
    assert not check_limits(op3, q, 0.01, q_start=op3.lower).ok  # a robot at the other end


def test_check_limits_finds_violations(op3: RobotConfig) -> None:
    q = np.tile(op3.init_pose, (3, 1))
    assert check_limits(op3, q, 0.01).ok
    q[1, 0] = op3.upper[0] + 0.1
    bad = check_limits(op3, q, 0.01)
    assert not bad.ok
    assert bad.position_excess_rad == pytest.approx(0.1)
    assert bad.velocity_excess_rad > 0


def test_written_trajectory_round_trips(step: RetargetStep, demo: HumanMotion,
                                       tmp_path: Path) -> None:  # fmt: skip
    traj = convert_motion(demo.frames(0, 15), step, fps=30.0).trajectory
    for suffix in (".npz", ".csv", ".json"):
        path = traj.write(tmp_path / f"t{suffix}")
        back = RobotTrajectory.read(path)
        np.testing.assert_allclose(back.q, traj.q, atol=1e-9)
        assert back.root_quat is not None


def test_output_paths_keep_the_folder_structure(tmp_path: Path) -> None:
    (tmp_path / "in" / "a").mkdir(parents=True)
    (tmp_path / "in" / "a" / "x.bvh").write_text("")
    (tmp_path / "in" / "y.BVH").write_text("")
    (tmp_path / "in" / "notes.txt").write_text("")
    pairs = output_paths(tmp_path / "in", tmp_path / "out", ".csv")
    assert [(c.name, o.relative_to(tmp_path / "out").as_posix()) for c, o in pairs] == [
        ("x.bvh", "a/x.csv"),
        ("y.BVH", "y.csv"),
    ]
    single = output_paths(tmp_path / "in" / "y.BVH", tmp_path / "o.npz", ".npz")
    assert single == [(tmp_path / "in" / "y.BVH", tmp_path / "o.npz")]


def test_a_converted_real_clip_follows_the_performer(shared_data_dir: Path) -> None:
    """Fidelity, not just shape: on a real walk the robot's segment directions, standing on the
    trajectory's own floating base, follow the performer's (eval-robot's measure), far better
    than the init pose held still would."""
    from robot_retarget.evaluation.robot.metrics import segment_angles
    from robot_retarget.evaluation.robot.segments import RobotBodyModel, human_body_points
    from robot_retarget.geometry import quaternion as quat
    from robot_retarget.motion.human_motion import load_motion
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config("op3")
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh")
    traj = convert_motion(motion, RetargetStep(config, "default", motion.skeleton)).trajectory
    q = traj.q
    assert traj.root_quat is not None
    base = quat.to_matrix(traj.root_quat)
    human = motion.resample(config.control_rate_hz).positions()[: len(q)]
    body = RobotBodyModel(config)
    converted = np.degrees(segment_angles(human_body_points(human), body.body_points(q, base)))
    held = np.tile(config.init_pose, (len(q), 1))
    still = np.degrees(segment_angles(human_body_points(human), body.body_points(held, base)))
    assert converted.mean() < 15.0, converted.mean()  # measured: 9.3° (held still: 44°)
    assert converted.mean() < 0.5 * still.mean(), (converted.mean(), still.mean())
