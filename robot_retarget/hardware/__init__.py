"""Hardware layer: stage types, the JointBackend interface, the Dynamixel backend (packets,
buses, control tables), the safety layer and a serial-free simulated backend.

Import submodules directly (``robot_retarget.hardware.dynamixel_backend``) so that code that
only needs the types never imports dynamixel_sdk.
"""

from robot_retarget.hardware.backend import JointBackend
from robot_retarget.hardware.types import JointCommand, JointState

__all__ = ["JointBackend", "JointCommand", "JointState"]
