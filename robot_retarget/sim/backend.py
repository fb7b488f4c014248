"""SimBackend: a JointBackend on the kinematic robot simulator, no serial port at all.

Each joint follows its goal with a first-order lag and its config max velocity, within the
config's joint limits (:class:`robot_retarget.sim.kinematic.KinematicRobot`). Real time by
default; with ``realtime=False`` the simulation advances to each command's ``t_s`` instead (offline
runs).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import HardwareError
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.hardware.types import JointCommand, JointState
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import as_robot_config
from robot_retarget.robot.pose_check import checked_pose
from robot_retarget.sim.kinematic import KinematicRobot


class SimBackend(JointBackend):
    def __init__(
        self,
        config: RobotConfig | str | os.PathLike[str],
        *,
        q0: FloatArray | None = None,
        time_constant_s: float = 0.01,
        realtime: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        config = as_robot_config(config)
        self.config = config
        self.q0 = checked_pose(config, config.init_pose if q0 is None else q0, "q0")
        self.time_constant_s = time_constant_s
        self.realtime = realtime
        self._clock = clock
        self.robot: KinematicRobot | None = None
        self._t_s = 0.0
        self.sent: list[JointCommand] = []

    @property
    def connected(self) -> bool:
        return self.robot is not None

    def connect(self) -> None:
        c = self.config
        self.robot = KinematicRobot(
            self.q0, c.max_velocity, c.lower, c.upper, time_constant_s=self.time_constant_s
        )
        self._t_s = self._clock() if self.realtime else 0.0

    def disconnect(self) -> None:
        self.robot = None

    def _require(self) -> KinematicRobot:
        if self.robot is None:
            raise HardwareError(f"SimBackend for {self.config.name}: connect() first")
        return self.robot

    def _advance_to(self, t_s: float) -> None:
        robot = self._require()
        if t_s > self._t_s:
            robot.advance(t_s - self._t_s)
            self._t_s = t_s

    def send(self, cmd: JointCommand) -> JointCommand:
        robot = self._require()
        if cmd.q.shape != (self.config.num_joints,) or not np.all(np.isfinite(cmd.q)):
            raise HardwareError(
                f"SimBackend: command must be {self.config.num_joints} finite angles, got "
                f"{cmd.q!r}; nothing was sent"
            )
        self._advance_to(self._clock() if self.realtime else cmd.t_s)
        robot.command(cmd.q)
        sent = JointCommand(robot.goal.copy(), cmd.t_s)
        self.sent.append(sent)
        return sent

    def read_state(self) -> JointState:
        robot = self._require()
        if self.realtime:
            self._advance_to(self._clock())
        n = self.config.num_joints
        return JointState(
            q=robot.q.copy(),
            velocity=robot.velocity.copy(),
            load=np.zeros(n),
            temperature=np.full(n, 30.0),
            hardware_error=np.zeros(n, dtype=np.int64),
            t_s=self._t_s,
        )
