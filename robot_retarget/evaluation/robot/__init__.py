"""Robot-side evaluation (``eval-robot``): does the robot visibly do what the person did?

- :mod:`.segments` — the nine scored segments (upper arms, forearms, thighs, shins, torso) for
  the human (canonical positions) and the robot (FK frames), in a heading-free body frame;
- :mod:`.metrics` — segment-direction angles, normalised end-effector errors, joint-limit and
  speed violations, jerk (numpy only);
- :mod:`.references` — targets of the position-IK baseline and the segments of the kinematic
  limit (both solved in :mod:`robot_retarget.optimize`);
- :mod:`.gmr_style` (with :mod:`.box_qp`) — the GMR-style baseline: per-frame differential IK of
  walked limb keypoints, foot orientations and a posture task, as GMR runs mink (numpy);
- :mod:`.runner` — converts clips with the full pipeline and scores pipeline, GMR-style IK,
  position-IK baseline and kinematic limit;
- :mod:`.report` / :mod:`.plots` — markdown table, goal check (issue #11), JSON, figures.

Measured with the shipped model as the robot path runs it (without its foot lock; ``python
launch.py eval-robot --robot ROBOT [--val-subjects …]``, 10 fps scoring, 2026-11-26; the tuning
set is what the optimizer's defaults were chosen on, the never-tuned set was looked at only at
the end). Every method stands on a
floating base, scored in the world: the pipeline on its trajectory's own (``root_quat``, the
network's trunk frames), the baselines and the limit on the performer's trunk frames.
Direction error mean over the nine segments (in brackets: over the eight limb segments); every
method had 0 joint-limit and 0 joint-speed violations:

========  ===========  =============  =============  =============  =============
robot     subjects     pipeline       GMR-style IK   position IK    limit
========  ===========  =============  =============  =============  =============
OP3       02 05 13 ¹   13.44 (14.59)  14.89 (16.64)  15.35 (17.15)   9.04 (10.06)
OP3       06 08 12 ²   12.36 (13.43)  11.26 (12.60)  12.09 (13.53)   8.66 ( 9.68)
OP3       03 07 10 14  13.05 (14.17)  14.84 (16.63)  15.87 (17.79)   7.28 ( 8.12)
Poppy     02 05 13 ¹    4.72 ( 4.73)   8.01 ( 5.43)  11.35 (10.84)   0.39 ( 0.43)
Poppy     06 08 12 ²    3.13 ( 3.13)   7.86 ( 4.14)  11.18 (10.96)   0.01 ( 0.01)
Poppy     03 07 10 14   3.24 ( 3.14)   5.41 ( 2.35)   9.22 ( 8.71)   0.01 ( 0.01)
========  ===========  =============  =============  =============  =============

End-effector error (limb lengths) / jerk (rad/s³):

========  ===========  ============  ============  ============  ======
robot     subjects     pipeline      GMR-style IK  position IK   limit
========  ===========  ============  ============  ============  ======
OP3       02 05 13 ¹   0.240 / 1378  0.252 / 2940  0.221 / 3678  0.218
OP3       06 08 12 ²   0.215 / 1417  0.205 / 3376  0.161 / 4235  0.181
OP3       03 07 10 14  0.236 / 1168  0.274 / 2183  0.250 / 2630  0.167
Poppy     02 05 13 ¹   0.138 / 1068  0.207 /  760  0.178 / 1287  0.206
Poppy     06 08 12 ²   0.117 /  988  0.180 /  794  0.165 / 1457  0.205
Poppy     03 07 10 14  0.116 /  905  0.188 /  649  0.167 / 1074  0.164
========  ===========  ============  ============  ============  ======

¹ tuning set; ² validation subjects (the default). Poppy's rows since its trunk bone follows
the torso line and the first frame's multi-start solves each limb without the spine (before:
4.73 (4.72) / 3.16 (3.12) / 3.49 (3.43), end-effector error 0.137 / 0.115 / 0.123), and since a
first frame is settled from two starts (:meth:`robot_retarget.optimize.Retargeter.settle`);
before that, on this machine, 5.64 (5.73) / 3.31 (3.27) / 3.66 (3.61), end-effector error 0.157
/ 0.134 / 0.139, with two first frames falling back on each of the tuning and never-tuned sets.
Before the trunk frame (limbs solved for an upright trunk, scored upright — the exported base
then tilted them, 20.7° off in the world on OP3 02/05/13): OP3 14.02 / 12.16 / 13.42, Poppy
4.91 / 3.64 / 3.72. Before issue #11's optimizer work: OP3 15.25° / 11.87° / 15.81°, Poppy
7.08° / 5.12° / 6.04°.

What is left on OP3 is its arms: three joints (no upper-arm twist, an elbow that bends both ways)
for two bone directions give several local optima, and a warm-started solve keeps the one it
starts in. Solved per frame to convergence with ideal targets (``--model oracle``, 02/05/13),
the optimum reached from the pipeline's pose scores 13.70°, the one reached from the limit's pose
11.17° (limit 10.09°); the cost itself prefers the limit's branch in 60–66 % of frames, but the
two lie > 0.6 rad apart, so moving there at the servos' speed costs more than it gains (see
:mod:`robot_retarget.optimize.limb_branches`). The network's targets add ≈ 0.5–0.7° on OP3 and
most of Poppy's gap (Poppy with ideal targets, 02/05/13: 2.94°, limbs 2.97°; 3.26° before the
trunk bone followed the torso line).
"""

from __future__ import annotations
