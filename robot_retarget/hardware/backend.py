"""The JointBackend interface every robot backend implements (Dynamixel, simulator, safety)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
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
        where they are sent as they are (then :meth:`rounded` is never called). The
        SafetyLayer keeps the rounded commands within ``v_max · dt`` of each other."""
        return None

    def set_command_period(self, period_s: float) -> None:
        """The time between commands of the loop that drives this backend (``stream --rate``
        may differ from the config's rate); a backend that checks steps on its own uses it.
        The SafetyLayer in front tells it its own."""
        return None

    def set_command_clock(self, clock: Callable[[], float]) -> None:
        """The clock (seconds) of the loop that drives this backend, where it is not the wall
        clock (a loop on simulated time); a backend that checks steps against the time that
        passed uses it. The SafetyLayer in front tells it its own."""
        return None

    def rounded(self, q: FloatArray) -> FloatArray:
        """(J,) the joint angles :meth:`send` would write for ``q`` (finite, in the limits)."""
        return q

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
