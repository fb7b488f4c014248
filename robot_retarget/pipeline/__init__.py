"""The pipeline: the one place that wires every stage together.

MotionSource → (FrameInterpolator) → RetargetStep (network online step → optimizer targets →
Retargeter.solve) → SafetyLayer → JointBackend, with one per-frame step for both paths:

- :func:`robot_retarget.pipeline.convert.convert_motion` — offline: a clip frame by frame into a
  RobotTrajectory (the SafetyLayer in front of a recording backend);
- :class:`robot_retarget.pipeline.loop.ControlLoop` — live: a fixed-rate loop with a watchdog,
  start-up ramp, smooth stop and live statistics, in front of a servo bus or the simulator.

The default model comes from :func:`robot_retarget.pipeline.defaults.default_model_name`.
Import submodules directly; this file imports nothing (torch and casadi load on demand).
"""
