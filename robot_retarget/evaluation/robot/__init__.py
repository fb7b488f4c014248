"""Robot-side evaluation (``eval-robot``): does the robot visibly do what the person did?

- :mod:`.segments` — the nine scored segments (upper arms, forearms, thighs, shins, torso) for
  the human (canonical positions) and the robot (FK frames), in a heading-free body frame;
- :mod:`.metrics` — segment-direction angles, normalised end-effector errors, joint-limit and
  speed violations, jerk (numpy only);
- :mod:`.references` — targets of the position-IK baseline and the segments of the kinematic
  limit (both solved in :mod:`robot_retarget.optimize`);
- :mod:`.runner` — converts clips with the full pipeline and scores pipeline, baseline, limit;
- :mod:`.report` / :mod:`.plots` — markdown table, goal check, JSON, matplotlib figures.

Measured on OP3, validation subjects 06, 08, 12 (23 clips, 959 evaluation frames at 10 fps;
``python launch.py eval-robot --robot op3 --data ../shared/data/mocap``, ≈ 20–30 s on one core):

===========================================  =========  =========  ==========  =========
direction error (°) / end-effector / jerk     pipeline   + settle   baseline    limit
===========================================  =========  =========  ==========  =========
model ``copy`` (the default until a            18.50      —          12.70       9.22
checkpoint ships): 0.273 / 1990 rad/s³                              0.163/3548  0.185
``--model oracle`` (ideal network)             13.14      11.54 ¹    12.70       9.22
===========================================  =========  =========  ==========  =========

¹ ``--settle-s 1`` (baseline 11.00°, limit 9.33° on the same frames). Both pipelines and the
baseline have 0 limit and 0 speed violations. With ideal targets the remaining gap to the limit
(settled, first 600 frames per clip: 11.01 − 9.08 = 1.9°) splits into the servo speed limit and
smoothing (≈ 1.0°: 10 × the speed and no smoothing give 9.97°), the roll / init terms (0.2°)
and warm-started local minima of the arms (0.7°: a multi-start solve of the same squared-chord
cost reaches 8.95° where the angle-optimal limit is 8.78°). With ``copy`` the network's targets
dominate: CMU's rest thighs point 20° outwards, so copying joint rotations onto the robot's
straight-legged skeleton turns OP3's thighs 20° inwards (crossed legs in the stick figures).
"""

from __future__ import annotations
