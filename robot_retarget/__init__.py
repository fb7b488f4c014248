"""robot-retarget: make Dynamixel-servo humanoids move like a person."""

__version__ = "0.1.0"
