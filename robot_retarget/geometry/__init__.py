"""Rotations in numpy: unit quaternions (w, x, y, z) and Euler angles in any order."""

from robot_retarget.geometry import euler, quaternion

__all__ = ["euler", "quaternion"]
