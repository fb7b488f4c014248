"""Tests of robot_retarget.optimize."""
