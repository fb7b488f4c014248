"""A robot's simulated Dynamixel buses on pseudo-terminals, for the demo and end-to-end tests.

The real dynamixel-sdk opens the pty like a USB adapter; the simulated servos
(robot_retarget.sim.dxl_bus) answer byte for byte in a background thread. Reply time over a pty
with the simulator in the
same Python process is a few milliseconds, not the microseconds of a real bus, so the packet
timeout is raised to ``packet_timeout_ms`` (20 ms) here.
"""

from __future__ import annotations

import os
from types import TracebackType

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.hardware.bus import buses_from_config
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import as_robot_config
from robot_retarget.robot.pose_check import checked_pose
from robot_retarget.sim.dxl_bus import SimulatedBus, buses_for_robot


class SimulatedRobotBus:
    """``with SimulatedRobotBus(config, q0) as sim: backend = sim.backend()``."""

    def __init__(
        self,
        config: RobotConfig | str | os.PathLike[str],
        q_rad: npt.ArrayLike | None = None,
        *,
        packet_timeout_ms: float = 20.0,
    ) -> None:
        config = as_robot_config(config)
        self.config = config
        q = checked_pose(config, config.init_pose if q_rad is None else q_rad, "q_rad")
        self.buses: dict[str, SimulatedBus] = buses_for_robot(config, q_rad=list(q))
        self.ports: dict[str, str] = {}
        self.packet_timeout_ms = packet_timeout_ms

    def start(self) -> None:
        for name, bus in self.buses.items():
            self.ports[name] = bus.start()

    def stop(self) -> None:
        for bus in self.buses.values():
            bus.stop()

    def __enter__(self) -> SimulatedRobotBus:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def settle(self, timeout_s: float = 2.0) -> None:
        """Wait until the simulator has processed every byte sent so far (read states after
        this: a Sync Write gets no reply, so the client may return before it is applied)."""
        for bus in self.buses.values():
            bus.settle(timeout_s=timeout_s)

    def backend(self) -> DynamixelBackend:
        """A DynamixelBackend (real SDK) on the simulated ports; signals left to the caller."""
        buses = buses_from_config(self.config, self.ports)
        for bus in buses.values():
            bus.packet_timeout_ms = max(bus.packet_timeout_ms, self.packet_timeout_ms)
        return DynamixelBackend(self.config, buses, handle_signals=False)

    def _servo_values(self, attr: str) -> FloatArray:
        out = np.empty(self.config.num_joints)
        for i, joint in enumerate(self.config.joints):
            servo = self.buses[joint.bus].servos[joint.servo_id]
            servo_rad = float(getattr(servo, attr))
            out[i] = (servo_rad - joint.zero_offset_rad) / joint.direction
        return out

    def present_q(self) -> FloatArray:
        """Joint angles (rad, config order) where the simulated horns are now."""
        return self._servo_values("present_rad")

    def goal_q(self) -> FloatArray:
        """The last goal positions the servos received (rad, config order)."""
        return self._servo_values("goal_rad")

    def torque_on(self) -> list[bool]:
        return [self.buses[j.bus].servos[j.servo_id].torque_on for j in self.config.joints]

    def packets(self) -> int:
        """Packets the buses accepted so far."""
        return sum(len(b.log.packets) for b in self.buses.values())
