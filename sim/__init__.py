"""Simulation without hardware: a byte-level Dynamixel bus on a pseudo-terminal and a kinematic
servo/robot model."""
