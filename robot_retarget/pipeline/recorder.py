"""RecordingBackend: a JointBackend that only remembers what it was sent (convert's "robot")."""

from __future__ import annotations

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import HardwareError
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.hardware.types import JointCommand, JointState
from robot_retarget.robot.config import RobotConfig


class RecordingBackend(JointBackend):
    """Reports ``q0`` (default: the init pose) until commanded; then the last command."""

    def __init__(self, config: RobotConfig, q0: FloatArray | None = None) -> None:
        self.config = config
        self._q = np.array(config.init_pose if q0 is None else q0, dtype=np.float64)
        self._connected = False
        self.sent: list[JointCommand] = []

    @property
    def connected(self) -> bool:
        return self._connected

    def connect(self) -> None:
        self._connected = True

    def disconnect(self) -> None:
        self._connected = False

    def send(self, cmd: JointCommand) -> JointCommand:
        if not self._connected:
            raise HardwareError("RecordingBackend: connect() first")
        self._q = np.array(cmd.q, dtype=np.float64)
        self.sent.append(cmd)
        return cmd

    def read_state(self) -> JointState:
        n = self.config.num_joints
        return JointState(
            q=self._q.copy(),
            velocity=np.zeros(n),
            load=np.zeros(n),
            temperature=np.zeros(n),
            hardware_error=np.zeros(n, dtype=np.int64),
        )
