"""robot-retarget: make Dynamixel-servo humanoids move like a person.

The public API, imported lazily (``import robot_retarget`` loads neither torch nor casadi until a
name that needs them is used)::

    import robot_retarget as rr
    result = rr.retarget("walk.bvh", robot="op3")
    result.trajectory.write("walk_op3.npz")
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name → (module, attribute)
_EXPORTS: dict[str, tuple[str, str]] = {
    "retarget": ("robot_retarget.api", "retarget"),
    "RetargetResult": ("robot_retarget.api", "RetargetResult"),
    "load_robot": ("robot_retarget.robot.loader", "load_robot_config"),
    "available_robots": ("robot_retarget.robot.loader", "available_robots"),
    "RobotConfig": ("robot_retarget.robot.config", "RobotConfig"),
    "load_motion": ("robot_retarget.motion.human_motion", "load_motion"),
    "HumanMotion": ("robot_retarget.motion.human_motion", "HumanMotion"),
    "load_model": ("robot_retarget.runtime.loader", "load_runtime_model"),
    "Retargeter": ("robot_retarget.optimize.retargeter", "Retargeter"),
    "RetargetStep": ("robot_retarget.pipeline.step", "RetargetStep"),
    "PositionsToRotations": ("robot_retarget.sources.from_positions", "PositionsToRotations"),
    "RobotTrajectory": ("robot_retarget.motion.trajectory", "RobotTrajectory"),
    "JointCommand": ("robot_retarget.hardware.types", "JointCommand"),
    "SafetyLayer": ("robot_retarget.hardware.safety", "SafetyLayer"),
    "DynamixelBackend": ("robot_retarget.hardware.dynamixel_backend", "DynamixelBackend"),
    "SimBackend": ("robot_retarget.sim.backend", "SimBackend"),
    "SimulatedRobotBus": ("robot_retarget.sim.robot_bus", "SimulatedRobotBus"),
    "RetargetError": ("robot_retarget.errors", "RetargetError"),
}

__all__ = [
    "DynamixelBackend",
    "HumanMotion",
    "JointCommand",
    "PositionsToRotations",
    "RetargetError",
    "RetargetResult",
    "RetargetStep",
    "Retargeter",
    "RobotConfig",
    "RobotTrajectory",
    "SafetyLayer",
    "SimBackend",
    "SimulatedRobotBus",
    "__version__",
    "available_robots",
    "load_model",
    "load_motion",
    "load_robot",
    "retarget",
]  # the names of _EXPORTS (a test keeps the two equal)

if TYPE_CHECKING:
    from robot_retarget.api import RetargetResult, retarget
    from robot_retarget.errors import RetargetError
    from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
    from robot_retarget.hardware.safety import SafetyLayer
    from robot_retarget.hardware.types import JointCommand
    from robot_retarget.motion.human_motion import HumanMotion, load_motion
    from robot_retarget.motion.trajectory import RobotTrajectory
    from robot_retarget.optimize.retargeter import Retargeter
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.robot.config import RobotConfig
    from robot_retarget.robot.loader import available_robots
    from robot_retarget.robot.loader import load_robot_config as load_robot
    from robot_retarget.runtime.loader import load_runtime_model as load_model
    from robot_retarget.sim.backend import SimBackend
    from robot_retarget.sim.robot_bus import SimulatedRobotBus
    from robot_retarget.sources.from_positions import PositionsToRotations


def __getattr__(name: str) -> Any:
    try:
        module, attribute = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'robot_retarget' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value  # once imported, a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
