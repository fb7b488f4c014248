"""The JointBackend interface every robot backend implements (Dynamixel, simulator, safety)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType

from robot_retarget.array_types import FloatArray
from robot_retarget.hardware.types import JointCommand, JointState
from robot_retarget.robot.config import RobotConfig


class JointBackend(ABC):
    """Connect, stream commands, read state, disconnect. A context manager: ``with backend:``
    connects and always disconnects (torque off on a real robot), whatever happened."""

    config: RobotConfig

    @abstractmethod
    def connect(self) -> None:
        """Open the bus(es), check the servos, make the robot ready to take commands."""

    @abstractmethod
    def read_state(self) -> JointState:
        """Present joint state in config joint order."""

    @abstractmethod
    def send(self, cmd: JointCommand) -> JointCommand:
        """Send a command; returns the command actually sent (after any clipping/rounding)."""

    @abstractmethod
    def disconnect(self) -> None:
        """Release the robot (torque off) and close the bus(es). Safe to call twice."""

    @property
    @abstractmethod
    def connected(self) -> bool:
        """Whether connect() succeeded and disconnect() has not run since."""

    @property
    def position_quantum_rad(self) -> FloatArray | None:
        """(J,) the resolution commands are rounded to on the way out (a servo tick), or None
        where they are sent as they are. The SafetyLayer keeps that much under the step bound,
        so that the rounding cannot take a step past ``v_max · dt``."""
        return None

    def __enter__(self) -> JointBackend:
        self.connect()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.disconnect()
