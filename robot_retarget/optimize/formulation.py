"""The retargeting problem for a window of W frames as one CasADi SX NLP, built once per robot.

Decision variables: q_0 … q_{W−1} (W·J). Everything that changes per call is a parameter or a
bound, so one compiled solver serves every frame:

- parameters: whatever the objective's named cost terms declare (:mod:`.objective`,
  :mod:`.terms`: per frame e.g. bone target directions and weights; shared e.g. smoothness
  weights), plus the committed history q_{−1}, q_{−2} and 1/dt, laid out once by name
  (:mod:`.parameter_layout`);
- variable bounds: joint limits merged with the velocity box (computed in numpy per call);
- constraint rows: per frame the twist of every bone (one ``atan2`` row each, bounds ±α) and the
  height of each foot (lower bound −root height; −10⁹ m when unknown); for t ≥ 1 the velocity rows
  q_t − q_{t−1} ∈ ±v_max·dt. W = 1 is the online problem (no velocity rows: the box does it).

The cost is ``|r|²`` of one vector of weighted residuals ``r`` (the terms' residuals of every
frame, returned as ``nlp["r"]``), so the solver can use the Gauss–Newton Hessian 2·JᵀJ as well
as the exact one.

Twist without quaternions: for a rotation R with axial vector ``ax(R) = ½(R₃₂−R₂₃, R₁₃−R₃₁,
R₂₁−R₁₂) = 2w·v`` and ``1 + tr R = 4w²``, the swing–twist twist angle about unit ``a`` is
``2·atan2(a·v, w) = 2·atan2(a·ax(R), ½(1 + tr R))`` — one smooth row, exact for w ≥ 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.bone_model import (
    BoneGeometry,
    alignment,
    body_to_root,
    build_bones,
    canonical_to_root,
    end_effector_frames,
    foot_frames,
)
from robot_retarget.optimize.parameter_layout import Parameter, ParameterLayout
from robot_retarget.optimize.symbolic_kinematics import SymbolicKinematics
from robot_retarget.robot.config import RobotConfig

if TYPE_CHECKING:  # the objective's terms build on this module
    from robot_retarget.optimize.objective import Objective

_NORM_EPS = 1e-12  # keeps the bone-length sqrt differentiable at zero length


def twist_expr(r: ca.SX, axis: FloatArray) -> ca.SX:
    """Swing–twist twist angle (rad) of rotation matrix ``r`` about unit ``axis``."""
    ax = 0.5 * ca.vertcat(r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1])
    return 2.0 * ca.atan2(ca.dot(ca.SX(axis), ax), 0.5 * (1.0 + ca.trace(r)))


@dataclass(frozen=True)
class FrameQuantities:
    """The robot's forward kinematics at one frame's joint angles (SX), for the cost terms."""

    bone_directions: ca.SX  # (3B,) unit, root frame
    bone_normals: ca.SX  # (3B,) unit
    ee_positions: ca.SX  # (3E,) m, root frame
    bone_vectors: ca.SX  # (3B,) m, end minus start frame of each bone, root frame


# Constraint rows g of a window: per frame the twist of every bone and each foot's height,
# then (W ≥ 2) the velocity rows q_t − q_{t−1}, t = 1 … W−1, after the frame blocks.
TWIST_ROWS = "twist"
FOOT_ROWS = "foot_height"


class RobotProblem:
    """Per-robot geometry (bones, frames, numeric FK) shared by every window size."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        self.num_joints = config.num_joints
        q = ca.SX.sym("q", self.num_joints)
        kin = SymbolicKinematics(config, q)
        for frame in {f for b in config.bones for f in (b.start_frame, b.end_frame)}:
            kin.pose(frame)  # raises ConfigError naming unknown frames
        carrier_of = {b.end_frame: kin.carrier_link(b.end_frame) for b in config.bones}
        self.bones: tuple[BoneGeometry, ...] = build_bones(config, carrier_of)
        self.ee_frames = end_effector_frames(config)
        self.feet = foot_frames(config)
        self.constraint_layout = ParameterLayout(
            (Parameter(TWIST_ROWS, len(self.bones)), Parameter(FOOT_ROWS, len(self.feet)))
        )
        # Numeric FK at q = 0 fixes each bone's alignment constant.
        zero = np.zeros(self.num_joints)
        starts = tuple(b.start_frame for b in self.bones)
        ends = tuple(b.end_frame for b in self.bones)
        carriers = tuple(b.carrier_link for b in self.bones)
        p_start = np.asarray(kin.positions_function(starts)(zero))
        p_end = np.asarray(kin.positions_function(ends)(zero))
        r_car = np.asarray(kin.rotations_function(carriers)(zero))
        self.alignments: tuple[FloatArray, ...] = tuple(
            alignment(b, p_end[:, k] - p_start[:, k], r_car[:, 3 * k : 3 * k + 3])
            for k, b in enumerate(self.bones)
        )
        self.body_to_root = body_to_root(config)
        self.canonical_to_root = canonical_to_root(config)
        # The robot's "hips": mid-point of the thigh start frames at q = 0 (end-effector targets
        # are given relative to the human hips); the root origin when no thigh is mapped.
        hips = tuple(
            b.start_frame for b in self.bones if b.canonical in ("LeftUpLeg", "RightUpLeg")
        )
        self.hip_center = (
            np.asarray(kin.positions_function(hips)(zero)).mean(axis=1) if hips else np.zeros(3)
        )
        self._q = q
        self._kin = kin
        # Per-frame expressions of q, reused by every window size through substitution.
        self.bone_lengths = np.linalg.norm(p_end - p_start, axis=0)  # (B,) m, at q = 0
        self.bone_vectors = [
            kin.position(b.end_frame) - kin.position(b.start_frame) for b in self.bones
        ]
        self.bone_dirs = [self._direction(b) for b in self.bones]
        self.bone_rots = [
            kin.rotation(b.carrier_link) @ ca.SX(c)
            for b, c in zip(self.bones, self.alignments, strict=True)
        ]
        self.bone_normals = [
            r @ ca.SX(b.rest_normal) for r, b in zip(self.bone_rots, self.bones, strict=True)
        ]
        self.twists = [self._twist(k) for k in range(len(self.bones))]
        self.up = np.asarray(config.up_axis, dtype=np.float64) / np.linalg.norm(config.up_axis)
        self.foot_heights = [ca.dot(ca.SX(self.up), kin.position(f)) for f in self.feet]
        self.ee_positions = [kin.position(f) for _, f in self.ee_frames]
        # Numeric versions (q → value) for targets, tests and evaluation.
        self.directions_function = ca.Function("bone_dirs", [q], [ca.horzcat(*self.bone_dirs)])
        self.normals_function = ca.Function("bone_normals", [q], [ca.horzcat(*self.bone_normals)])
        self.twists_function = ca.Function("bone_twists", [q], [ca.vertcat(*self.twists)])
        self.ee_function = ca.Function(
            "ee_positions",
            [q],
            [ca.horzcat(*self.ee_positions)] if self.ee_positions else [ca.SX(3, 0)],
        )
        self.feet_function = ca.Function(
            "foot_heights", [q], [ca.vertcat(*self.foot_heights)] if self.feet else [ca.SX(0, 1)]
        )

    def _direction(self, bone: BoneGeometry) -> ca.SX:
        v = self._kin.position(bone.end_frame) - self._kin.position(bone.start_frame)
        return v / ca.sqrt(ca.sumsqr(v) + _NORM_EPS)

    def _twist(self, k: int) -> ca.SX:
        bone = self.bones[k]
        r = self.bone_rots[k]
        local = r if bone.parent < 0 else self.bone_rots[bone.parent].T @ r
        return twist_expr(local, bone.rest_axis)

    @property
    def num_constraints_per_frame(self) -> int:
        return self.constraint_layout.frame_size

    def build_nlp(self, window: int, objective: Objective | None = None) -> dict[str, ca.SX]:
        """The NLP dict (x, p, f, g, r) for ``window`` frames solved jointly; ``p`` is laid out
        by ``objective`` (default: the Retargeter's terms with default settings)."""
        if objective is None:
            from robot_retarget.optimize.objective import retarget_objective
            from robot_retarget.robot.retarget_settings import RetargetSettings

            objective = retarget_objective(self, RetargetSettings())
        j = self.num_joints
        nb, ne = len(self.bones), len(self.ee_frames)
        x = ca.SX.sym("x", window * j)
        p = ca.SX.sym("p", objective.layout.size(window))
        per_frame = ca.vertcat(
            *self.bone_dirs,
            *self.bone_normals,
            *self.ee_positions,
            *self.twists,
            *self.foot_heights,
            *self.bone_vectors,
        )
        frame_fn = ca.Function("frame_terms", [self._q], [per_frame])
        g_end = 6 * nb + 3 * ne + self.num_constraints_per_frame
        res: list[ca.SX] = []  # weighted residuals: cost = |res|², Gauss–Newton Hessian 2 JᵀJ
        g_rows: list[ca.SX] = []
        q_prev2, q_prev = objective.history(p)
        history = [q_prev2, q_prev]
        for t in range(window):
            qt = x[t * j : (t + 1) * j]
            terms = frame_fn(qt)
            robot = FrameQuantities(
                bone_directions=terms[0 : 3 * nb],
                bone_normals=terms[3 * nb : 6 * nb],
                ee_positions=terms[6 * nb : 6 * nb + 3 * ne],
                bone_vectors=terms[g_end:],
            )
            res.extend(objective.residuals(t, p, qt, (history[-2], history[-1]), robot))
            g_rows.append(terms[6 * nb + 3 * ne : g_end])  # twists, then foot heights
            history.append(qt)
        for t in range(1, window):
            g_rows.append(x[t * j : (t + 1) * j] - x[(t - 1) * j : t * j])
        r = ca.vertcat(*res)
        return {"x": x, "p": p, "f": ca.sumsqr(r), "g": ca.vertcat(*g_rows), "r": r}
