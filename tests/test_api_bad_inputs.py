"""Bad values handed to the public API's simulator, robot loader and trajectory raise a
RetargetError naming what was wrong (they raised numpy's IndexError, a broadcast error at
connect, a TypeError, or took a NaN pose in silently)."""

from __future__ import annotations

import numpy as np
import pytest

import robot_retarget as rr
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sim.robot_bus import SimulatedRobotBus


@pytest.mark.parametrize(
    ("pose", "says"),
    [
        (np.full(20, np.nan), r"is nan for joint r_sho_pitch: angles must be finite"),
        (np.zeros(4), r"must be one angle per joint of op3, 20 in its joint order, got shape"),
        ("abc", r"must be 20 numbers"),
        (np.full(20, 30.0), r"is 30 for joint r_sho_pitch, more than a turn: angles are radians"),
    ],
)
def test_a_simulator_start_pose_is_checked(pose: object, says: str) -> None:
    config = rr.load_robot("op3")
    with pytest.raises(rr.RetargetError, match="q_rad " + says):
        SimulatedRobotBus(config, pose)  # type: ignore[arg-type]
    with pytest.raises(rr.RetargetError, match="q0 " + says):
        SimBackend(config, q0=pose)  # type: ignore[arg-type]


def test_a_robot_named_by_nothing_is_a_config_error() -> None:
    with pytest.raises(rr.RetargetError, match="named by a config name or a YAML path, got None"):
        rr.load_robot(None)  # type: ignore[arg-type]


def test_a_trajectory_built_from_impossible_values_is_a_retarget_error() -> None:
    with pytest.raises(rr.RetargetError, match="q must have shape"):
        rr.RobotTrajectory(("a", "b"), np.zeros((5, 3)), 125.0)
    with pytest.raises(ValueError, match="fps must be positive"):  # still a ValueError too
        rr.RobotTrajectory(("a",), np.zeros((5, 1)), 0.0)


def test_the_classes_take_a_robot_by_name_or_path_and_the_performer_as_a_motion() -> None:
    """A user passes "op3" as load_robot takes it (each had failed with an AttributeError)."""
    from robot_retarget.motion.synthetic import demo_motion

    path = rr.load_robot("op3").source_path
    assert path is not None
    motion = demo_motion(fps=30.0).frames(0, 3)
    sim = SimBackend("op3", realtime=False)
    safe = rr.SafetyLayer(path, sim, clock=None)
    step = rr.RetargetStep("op3", "copy", motion)  # a motion stands for its skeleton
    safe.connect()
    out = step(motion.local_quats[0], motion.root_pos[0], 1 / 125)
    safe.send(rr.JointCommand(out.q, 0.008))
    assert safe.config.name == sim.config.name == step.config.name == "op3"
    assert SimulatedRobotBus("op3").config.name == "op3"
    with pytest.raises(rr.RetargetError, match=r"a bundled robot's name .*got int"):
        SimBackend(3)  # type: ignore[arg-type]
    with pytest.raises(rr.RetargetError, match="the performer is a Skeleton"):
        rr.RetargetStep("op3", "copy", "walk.bvh")  # type: ignore[arg-type]


def test_quaternions_sent_x_y_z_w_are_warned_of_once() -> None:
    """scipy's as_quat() order: the robot plays another motion (0.8 rad off on average) with no
    error; after a second of such frames the step warns, once."""
    import warnings

    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.pipeline.step import ConventionWarning

    motion = demo_motion(fps=30.0).frames(0, 60)
    for roll, warned in ((0, 0), (-1, 1)):
        step = rr.RetargetStep("op3", "copy", motion)
        step.reset()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for k in range(motion.num_frames):
                step(np.roll(motion.local_quats[k], roll, axis=-1), motion.root_pos[k], 1 / 30)
        tells = [w for w in caught if issubclass(w.category, ConventionWarning)]
        assert len(tells) == warned
        if warned:
            assert "x-y-z-w" in str(tells[0].message)


def test_joint_positions_go_in_through_the_exported_solver() -> None:
    """A pose estimator's 22 canonical joint positions → rotations for RetargetStep; a wrong
    shape, a NaN and a frame of the wrong joint count are RetargetErrors (they were ValueErrors
    from inside the network, or a NaN taken in)."""
    from robot_retarget.motion.synthetic import demo_motion

    motion = demo_motion(fps=30.0).frames(0, 2)
    solver = rr.PositionsToRotations()  # the canonical skeleton's proportions
    local, root = solver.solve(motion.positions()[0])
    step = rr.RetargetStep("op3", "copy", solver.skeleton)
    step.reset()
    assert np.isfinite(step(local, root, 1 / 30).q).all()
    with pytest.raises(rr.RetargetError, match=r"shape \(22, 3\), got \(17, 3\)"):
        solver.solve(np.zeros((17, 3)))
    with pytest.raises(rr.RetargetError, match="NaN"):
        solver.solve(np.full((22, 3), np.nan))
    with pytest.raises(rr.RetargetError, match="21 rows, the performer's skeleton 22 joints"):
        step(local[:21], root, 1 / 30)
