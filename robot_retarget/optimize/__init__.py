"""Constrained retargeting optimizer (CasADi): rotation wishes → servo angles within limits.

casadi is imported here, by :mod:`robot_retarget.casadi_jit` (JIT cache, in-place calls) and by
the SX graphs of the live path's per-frame steps (the network's geometry, position packets →
rotations, :mod:`robot_retarget.geometry.symbolic_quaternion`), nowhere else.
Entry point: :class:`Retargeter` — ``solve`` (online, one frame, warm-started) and
``solve_clip`` (offline, sliding windows solved jointly); targets come from
:func:`targets_from_rotations` (canonical local rotations → bone directions / normals / end
effectors in the trunk frame) or are built directly as :class:`FrameTargets`.

Formulation (per frame, see :mod:`.formulation`): a sum of named cost terms (:mod:`.terms`,
assembled by :mod:`.objective`, parameters laid out once by :mod:`.parameter_layout`) — unit
bone directions, bone normals (roll), optional end-effector and limb-keypoint positions,
velocity / acceleration smoothness and a pull to the init pose; hard: joint limits ∩ velocity
box as variable bounds, one ``atan2`` twist row per bone (±α, 100° by default), optional
feet-above-ground rows. Every output is projected onto the merged box and checked
(:mod:`.limits`). A sequence's first frame (:meth:`Retargeter.settle`) starts every limb in its
best branch (:mod:`.limb_branches`).

Solver choice, measured with ``bench solve`` on OP3 (20 joints, 12 bones, CMU 02_05 boxing,
first 1200 frames at 120 fps), one core (``taskset -c 1``) of the 2-core dev machine while other
jobs ran (load ≈ 2.5); per call from Python including validation and projection:

==============================================================  =======  =======  =====
online                                                          median   p99      iters
==============================================================  =======  =======  =====
sqpmethod + daqp, exact Hessian (eigen-reflect), JIT, buffer    0.14 ms  0.27 ms  4.4
the same without JIT (no C compiler)                            0.66 ms  2–6 ms   4.4
sqpmethod + daqp, Gauss–Newton Hessian, JIT, buffer             0.56 ms  4.8 ms   15 ¹
ipopt, expanded SX, warm start (300 frames)                     3.3 ms   8.7 ms   11
==============================================================  =======  =======  =====

¹ 404 of 1200 frames hit 20 iterations: unreachable targets leave large residuals, where
Gauss–Newton converges linearly. Eigen-clip instead of eigen-reflect is as fast on mocap but
took > 20 iterations (diverging) for far targets on Poppy's 5-joint spine.

===============================================================  ==========
offline (whole clip, wall time)                                   frames/s
===============================================================  ==========
online seed pass + GN windows of 16 (overlap 2), osqp, 2 iters   1985–2010
the same, 3 iterations per window                                 1530–1625
the same without JIT (seed pass interpreted)                      ≈ 640
GN windows of 8, qrqp, no seed, ≤ 20 iterations                   ≈ 210
exact Hessian (eigen-clip) windows of 8, daqp / qrqp              120–150
===============================================================  ==========

Windows lower joint acceleration (RMS) by 13–31 % against the online pass at equal or lower
bone-direction error (OP3 02_05: 41.6 → 32.3 rad/s², 05_02: 148 → 103 rad/s²; Poppy 05_02:
131 → 113 rad/s²). casadi 3.8.2's eigen convexification fails on Hessians of ≥ 60 variables
unless ``max_iter_eig`` is raised (issue #2973), and is then too slow for windows: hence the
Gauss–Newton Hessian (PSD by construction) for windows and the exact one per frame.
"""

from __future__ import annotations

from robot_retarget.optimize.result import SolveResult, SolveStatus
from robot_retarget.optimize.retargeter import ClipTiming, Retargeter
from robot_retarget.optimize.targets import (
    ClipTargets,
    FrameTargets,
    targets_from_globals,
    targets_from_rotations,
)
from robot_retarget.robot.retarget_settings import RetargetSettings

__all__ = [
    "ClipTargets",
    "ClipTiming",
    "FrameTargets",
    "RetargetSettings",
    "Retargeter",
    "SolveResult",
    "SolveStatus",
    "targets_from_globals",
    "targets_from_rotations",
]
