"""Command-line interface: ``python launch.py <command>`` or ``robot-retarget <command>``."""
