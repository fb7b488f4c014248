"""Which robot a trajectory file belongs to, when the user does not say.

Trajectory files carry joint names, not a robot name: the bundled config whose joint names are
exactly the file's is the robot. No match, or more than one, is an error that asks for
``--robot``.
"""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import RetargetError
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import available_robots, load_robot_config


class RobotGuessError(RetargetError):
    """No bundled robot, or several, have the trajectory's joints; ``candidates`` are the
    matching robot names (empty when none match)."""

    def __init__(self, candidates: list[str], known: list[str]) -> None:
        self.candidates = candidates
        self.known = known
        what = (
            f"several robots have its joints ({', '.join(candidates)})"
            if candidates
            else f"no bundled robot has exactly its joints (known: {', '.join(known)})"
        )
        super().__init__(f"cannot tell which robot the trajectory is for: {what}; pass --robot")


def robot_for_trajectory(trajectory: RobotTrajectory) -> RobotConfig:
    """The bundled robot config whose joint names are the trajectory's (any order)."""
    wanted = set(trajectory.joint_names)
    known = available_robots()
    matches = [
        config
        for config in (load_robot_config(name) for name in known)
        if set(config.joint_names) == wanted
    ]
    if len(matches) != 1:
        raise RobotGuessError([c.name for c in matches], known)
    return matches[0]


class TrajectoryMismatchError(RetargetError):
    """The trajectory's joints are not ``robot``'s: ``missing`` (the robot's joints it lacks)
    and ``extra`` (its joints the robot has not)."""

    def __init__(self, robot: str, missing: list[str], extra: list[str]) -> None:
        self.robot = robot
        self.missing = missing
        self.extra = extra
        super().__init__(
            f"the trajectory's joints are not {robot}'s ("
            + (f"{extra[0]!r} is not one of them" if extra else f"{missing[0]!r} is missing")
            + f"; {len(missing)} of {robot}'s missing, {len(extra)} unknown): pass the robot "
            "it was converted for with --robot"
        )


def joint_angles_for(config: RobotConfig, trajectory: RobotTrajectory) -> FloatArray:
    """The trajectory's angles (T, J) in ``config``'s joint order."""
    names = list(trajectory.joint_names)
    missing = [n for n in config.joint_names if n not in names]
    extra = [n for n in names if n not in config.joint_names]
    if missing or extra:
        raise TrajectoryMismatchError(config.name, missing, extra)
    order = [names.index(n) for n in config.joint_names]
    return np.asarray(trajectory.q[:, order], dtype=np.float64)
