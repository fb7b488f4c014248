"""Robot-side fidelity and safety metrics (numpy only).

- segment-direction error: angle (rad) between human and robot segment directions in the
  heading-free body frame (see :mod:`.segments`), per frame and segment;
- end-effector error: distance between human and robot hand / foot offsets, each normalised by
  its own limb length (a fraction of the arm or leg length);
- joint-limit violations, joint-speed violations (above the servo's maximum speed), maximum speed
  and jerk (mean |third difference of q| · fps³) of a trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.robot.segments import BodyPoints
from robot_retarget.robot.config import RobotConfig

# Numerical slack when counting violations: a solver output exactly on a bound is not a violation.
LIMIT_TOL_RAD = 1e-9
SPEED_TOL = 1e-9  # relative


def segment_angles(human: BodyPoints, robot: BodyPoints) -> FloatArray:
    """(T, S) angles (rad) between human and robot segment directions."""
    a, b = human.directions, robot.directions
    if a.shape != b.shape:
        raise ValueError(f"human {a.shape} and robot {b.shape} directions differ in shape")
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.asarray(np.arctan2(cross, np.sum(a * b, axis=-1)), dtype=np.float64)


def end_effector_errors(human: BodyPoints, robot: BodyPoints) -> FloatArray:
    """(T, E) distances between normalised human and robot end-effector offsets."""
    return np.asarray(
        np.linalg.norm(human.end_effectors - robot.end_effectors, axis=-1), dtype=np.float64
    )


@dataclass(frozen=True)
class TrajectoryStats:
    """Safety and smoothness of a (T, J) trajectory at ``fps``."""

    frames: int
    limit_violations: int  # (frame, joint) pairs outside [lower, upper]
    speed_violations: int  # (frame, joint) steps faster than the joint's max velocity
    max_speed_rad_s: float
    max_speed_ratio: float  # max over steps of |Δq| / (v_max · dt)
    jerk_rad_s3: float  # mean |Δ³q| · fps³ over frames and joints


def trajectory_stats(
    config: RobotConfig, q: npt.ArrayLike, fps: float, q_start: npt.ArrayLike | None = None
) -> TrajectoryStats:
    """Violations, speed and jerk; the first step is taken from ``q_start`` when given, else the
    steps between rows only (a conversion starts at its first frame)."""
    a = np.asarray(q, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != config.num_joints:
        raise ValueError(f"q must be (T, {config.num_joints}), got {a.shape}")
    from_start = a if q_start is None else np.vstack([np.asarray(q_start, np.float64)[None], a])
    outside = (a < config.lower - LIMIT_TOL_RAD) | (a > config.upper + LIMIT_TOL_RAD)
    speed = np.abs(np.diff(from_start, axis=0)) * fps  # (T or T-1, J) rad/s
    ratio = speed / config.max_velocity
    third = np.diff(a, n=3, axis=0)
    return TrajectoryStats(
        frames=int(a.shape[0]),
        limit_violations=int(np.count_nonzero(outside)),
        speed_violations=int(np.count_nonzero(ratio > 1.0 + SPEED_TOL)),
        max_speed_rad_s=float(np.max(speed, initial=0.0)),
        max_speed_ratio=float(np.max(ratio, initial=0.0)),
        jerk_rad_s3=float(np.mean(np.abs(third)) * fps**3) if third.size else 0.0,
    )
