"""Measured joint angles for the live page, where they cost the control loop nothing.

A real Dynamixel bus is read only by the loop's thread (two threads on one port collide, and a
Sync Read per tick would lengthen every tick), so there the page shows commands only. The
kinematic simulator (``--backend sim``) keeps its present angles in memory: the page reads
them from its own thread (a read of an array the simulator replaces, never a bus transaction).
"""

from __future__ import annotations

from robot_retarget.array_types import FloatArray
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.viewer.live_page import MeasureFn


def passive_measurement(backend: JointBackend) -> MeasureFn | None:
    """A function returning the measured angles without touching the bus, or None."""
    from robot_retarget.sim.backend import SimBackend

    if not isinstance(backend, SimBackend):
        return None
    sim = backend

    def measured() -> FloatArray | None:
        robot = sim.robot
        return None if robot is None else robot.q.copy()

    return measured
