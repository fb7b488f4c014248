"""Kinematic servo response: position control with a first-order lag, a velocity limit and
position limits. Used by the simulated Dynamixel servos and by SimBackend (no serial port)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_retarget.array_types import FloatArray


@dataclass
class ServoDynamics:
    """One joint: ``dq/dt = clip((goal - q) / time_constant_s, ±max_velocity_rad_s)``, exact
    first-order step for the lag, then the speed clip, then the position limits."""

    q_rad: float
    max_velocity_rad_s: float
    time_constant_s: float = 0.01
    lower_rad: float = -math.inf
    upper_rad: float = math.inf
    velocity_rad_s: float = 0.0

    def step(self, goal_rad: float, dt_s: float) -> float:
        if dt_s <= 0.0:
            return self.q_rad
        goal = min(max(goal_rad, self.lower_rad), self.upper_rad)
        lag = (goal - self.q_rad) * (1.0 - math.exp(-dt_s / self.time_constant_s))
        max_step = self.max_velocity_rad_s * dt_s
        delta = min(max(lag, -max_step), max_step)
        q = min(max(self.q_rad + delta, self.lower_rad), self.upper_rad)
        self.velocity_rad_s = (q - self.q_rad) / dt_s
        self.q_rad = q
        return q


class KinematicRobot:
    """All joints of a robot, vectorised: the same law as :class:`ServoDynamics` per joint."""

    def __init__(
        self,
        q0_rad: FloatArray,
        max_velocity_rad_s: FloatArray,
        lower_rad: FloatArray,
        upper_rad: FloatArray,
        time_constant_s: float = 0.01,
    ) -> None:
        self.lower = np.asarray(lower_rad, dtype=np.float64).copy()
        self.upper = np.asarray(upper_rad, dtype=np.float64).copy()
        self.q = np.clip(np.asarray(q0_rad, dtype=np.float64), self.lower, self.upper)
        self.goal = self.q.copy()
        self.velocity = np.zeros_like(self.q)
        self.max_velocity = np.asarray(max_velocity_rad_s, dtype=np.float64).copy()
        if time_constant_s <= 0.0:
            raise ValueError(f"time_constant_s must be > 0, got {time_constant_s}")
        self.time_constant_s = time_constant_s

    def command(self, goal_rad: FloatArray) -> None:
        self.goal = np.clip(np.asarray(goal_rad, dtype=np.float64), self.lower, self.upper)

    def advance(self, dt_s: float) -> FloatArray:
        """Move ``dt_s`` seconds towards the goal; returns the new positions (rad)."""
        if dt_s <= 0.0:
            return self.q
        lag = (self.goal - self.q) * (1.0 - math.exp(-dt_s / self.time_constant_s))
        step = np.clip(lag, -self.max_velocity * dt_s, self.max_velocity * dt_s)
        q = np.clip(self.q + step, self.lower, self.upper)
        self.velocity = (q - self.q) / dt_s
        self.q = q
        return q
