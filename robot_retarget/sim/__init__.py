"""Simulation without hardware, product code (the demo and ``--backend sim`` run on it).

- :mod:`~robot_retarget.sim.kinematic`: servo and robot dynamics (first-order lag, speed limit);
- :mod:`~robot_retarget.sim.servo`: one Dynamixel servo's control table and instructions;
- :mod:`~robot_retarget.sim.dxl_bus`: a byte-level Dynamixel bus (Protocol 1.0 and 2.0) on a
  pseudo-terminal, runnable as ``python -m robot_retarget.sim.dxl_bus --robot op3``;
- :mod:`~robot_retarget.sim.backend`: ``SimBackend``, a JointBackend on the kinematic model;
- :mod:`~robot_retarget.sim.robot_bus`: ``SimulatedRobotBus``, a robot's simulated buses with
  a real DynamixelBackend in front of them.

One way only: the simulator uses :mod:`robot_retarget.hardware` (protocol, control tables,
backend interface); nothing in ``hardware`` imports the simulator.
"""
