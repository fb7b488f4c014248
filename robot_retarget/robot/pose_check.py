"""A joint pose handed in from outside (a simulator's starting pose): one finite angle per
joint of the robot, or an error that says so (numpy's own were an IndexError or a broadcast
error deep inside, or a NaN taken in silently)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import BoolArray, FloatArray
from robot_retarget.errors import InvalidMotionError
from robot_retarget.robot.config import RobotConfig

ONE_TURN_RAD = 2.0 * np.pi
"""No joint of a humanoid's single-turn servos goes beyond this either way (the loader bounds
every limit by the servo's tick range and a zero offset of at most π): a pose or a command
past it is in other units, almost always degrees."""


def beyond_a_turn(q: FloatArray) -> BoolArray:
    """Per joint, whether ``q`` (finite, rad) lies beyond :data:`ONE_TURN_RAD`."""
    return np.abs(q) > ONE_TURN_RAD


def checked_pose(config: RobotConfig, q: npt.ArrayLike, what: str) -> FloatArray:
    """``q`` as (J,) radians for ``config``; InvalidMotionError naming ``what`` otherwise."""
    try:
        pose = np.array(q, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidMotionError(f"{what} must be {config.num_joints} numbers (radians)") from None
    if pose.shape != (config.num_joints,):
        raise InvalidMotionError(
            f"{what} must be one angle per joint of {config.name}, {config.num_joints} in its "
            f"joint order, got shape {pose.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(pose))
    if bad.size:
        raise InvalidMotionError(
            f"{what} is {pose[bad[0]]} for joint {config.joint_names[bad[0]]}: angles must be "
            "finite"
        )
    far = np.flatnonzero(beyond_a_turn(pose))
    if far.size:
        raise InvalidMotionError(
            f"{what} is {pose[far[0]]:g} for joint {config.joint_names[far[0]]}, more than a "
            "turn: angles are radians (degrees? pass np.radians of them)"
        )
    return pose
