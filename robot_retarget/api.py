"""Retarget a clip from Python in one call.

    import robot_retarget as rr
    result = rr.retarget("walk.bvh", robot="op3")
    result.trajectory.write("walk_op3.npz")

:func:`retarget` is what ``convert`` runs for one clip: the network's online step, the
optimizer within every joint and velocity limit, and the safety layer, frame by frame at the
robot's control rate (or ``fps``); the trajectory starts at the clip's first frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from robot_retarget.errors import RetargetError
from robot_retarget.motion.frame_rate import FPS_RANGE, plausible_fps
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import LEAD_IN_SPEED_FRACTION, ClipResult, convert_motion
from robot_retarget.pipeline.defaults import default_model_name
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.runtime.loader import load_runtime_model
from robot_retarget.runtime.model import RuntimeModel

if TYPE_CHECKING:
    from robot_retarget.nn.inference import LoadedModel


@dataclass(frozen=True)
class RetargetResult:
    """A retargeted clip: the robot trajectory and what happened on the way (frames, wall
    time, the limit check, safety clips and solver fallbacks)."""

    trajectory: RobotTrajectory
    report: ClipResult
    model: str


def retarget(
    clip_or_motion: HumanMotion | str | os.PathLike[str],
    robot: RobotConfig | str | os.PathLike[str] = "op3",
    model: RuntimeModel | LoadedModel | str | os.PathLike[str] | None = None,
    *,
    fps: float | None = None,
    foot_lock: bool = False,
    lead_in: bool = False,
) -> RetargetResult:
    """Retarget a BVH file (or a loaded :class:`HumanMotion`) to ``robot`` (a name, a YAML path
    or a loaded config) with ``model`` (a name, a runtime ``.npz`` or checkpoint path, or a
    loaded model; default: the shipped default — its numpy runtime, no torch needed), at ``fps``
    (default: the robot's control rate). ``foot_lock``: run the residual network's foot lock
    (off on the robot by default, as in ``convert``). ``lead_in``: prepend the move from the
    robot's init pose to the first frame at the ramp speed, stamped before t = 0, as
    ``convert --lead-in`` does (played from the init pose, a file without it starts with the
    move at the velocity limits that the safety layer allows)."""
    if fps is not None and not plausible_fps(fps):
        raise RetargetError(f"fps must be a frame rate, {FPS_RANGE}, got {fps!r}")
    if not isinstance(clip_or_motion, HumanMotion | str | os.PathLike):
        raise RetargetError(
            f"clip_or_motion must be a BVH path or a HumanMotion, got {type(clip_or_motion)!r}"
        )
    if not isinstance(robot, RobotConfig | str | os.PathLike):
        raise RetargetError(
            f"robot must be a name (e.g. 'op3'), a YAML path or a RobotConfig, got {robot!r}"
        )
    if not isinstance(clip_or_motion, HumanMotion) and Path(clip_or_motion).is_dir():
        raise RetargetError(
            f"{os.fspath(clip_or_motion)}: a folder; retarget takes one clip (convert converts "
            "a folder)"
        )
    motion = (
        clip_or_motion
        if isinstance(clip_or_motion, HumanMotion)
        else load_motion(os.fspath(clip_or_motion))
    )
    config = robot if isinstance(robot, RobotConfig) else load_robot_config(robot)
    if isinstance(model, str | os.PathLike) or model is None:
        loaded = load_runtime_model(os.fspath(model) if model is not None else default_model_name())
    else:
        loaded = model
    step = RetargetStep(config, loaded, motion.skeleton, rate_hz=fps, foot_lock=foot_lock)
    result = convert_motion(  # as convert
        motion,
        step,
        fps=fps,
        whole_clip_branches=True,
        lead_in_speed_fraction=LEAD_IN_SPEED_FRACTION if lead_in else None,
    )
    return RetargetResult(result.trajectory, result, loaded.name)
