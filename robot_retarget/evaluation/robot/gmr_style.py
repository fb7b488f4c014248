"""The GMR-style baseline: per-frame differential IK of frame tasks, as GMR does it with mink.

GMR (General Motion Retargeting, YanjieZe/GMR) scales the human's body positions to the robot
and, per frame, runs a few iterations of mink's differential IK: frame tasks (position and
orientation cost per body), a QP per iteration with the joint limits and a velocity limit,
damped least squares (``damping`` 0.5, Levenberg–Marquardt ``lm_damping`` 1 per frame task),
warm-started from the previous frame. This module does the same in numpy (no mink, no MuJoCo):

- targets: knee, ankle, elbow and wrist (hand point) *positions*, built by walking the
  performer's unit segment directions (heading-free body frame) along the **robot's** own
  segment lengths from the robot's hip and shoulder — the limb's first segment start where it
  is at the current iterate (OP3's and Poppy's upper-arm starts sit off the shoulder-pitch
  axis and move with it: walked from their place at q = 0, Poppy's left upper arm scored 30°
  instead of 1° on CMU 02_05), position cost 10 each; each foot link's *orientation* (the
  performer's foot rotation carried onto the robot's foot bone), cost 0.3; a posture task
  toward the init pose, cost 0.05;
- per frame 3 iterations of ``min Σ_k |W_k (J_k Δq − e_k)|² + Σ_k μ_k |Δq|² + λ |Δq|²`` over
  the box ``lower ≤ q + Δq ≤ upper``, ``|q + Δq − q_prev| ≤ v_max·dt`` (the robot's servo
  speeds, so the trajectory never exceeds them; mink bounds each iteration by ``v·dt`` of its
  own step instead), ``μ_k = lm_damping · |W_k e_k|²``; frame 0 iterated to convergence with
  the joint limits only.

GMR's task on the pelvis / torso body pose needs a floating base, which a fixed-base retargeter
does not have: it is left out, and eval-robot scores this baseline on its limb segments (the
torso is the trunk's fixed axis for every method here).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SolveError
from robot_retarget.evaluation.robot.box_qp import box_qp
from robot_retarget.evaluation.robot.references import LIMBS
from robot_retarget.evaluation.robot.segments import RobotSegmentFrames
from robot_retarget.geometry import quaternion as quat
from robot_retarget.optimize.bone_model import (
    alignment,
    body_to_root,
    build_bones,
    canonical_to_root,
)
from robot_retarget.optimize.chains import joints_above
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.trunk import trunk_frames_of_positions

_FEET = ("LeftFoot", "RightFoot")  # canonical foot joints (start of the foot bones)
_SETTLE_TOL_RAD = 1e-7
_SETTLE_MAX_ITER = 200


@dataclass(frozen=True)
class GMRStyleSettings:
    """Task costs (mink: residual weights) and solver settings."""

    position_cost: float = 10.0
    orientation_cost: float = 0.3
    posture_cost: float = 0.05
    damping: float = 0.5
    lm_damping: float = 1.0
    iterations: int = 3


@dataclass(frozen=True)
class GMRTargets:
    """Per frame: positions (T, P, 3) m of the position tasks relative to their limb's root,
    rotations (T, F, 3, 3) of the orientation tasks, both in the robot root frame."""

    positions: FloatArray
    rotations: FloatArray


@dataclass(frozen=True)
class GMRResult:
    q: FloatArray  # (T, J)
    solve_time_s: float


def _carrier(config: RobotConfig, frame: str) -> str:
    """The link that carries a frame's origin (as the optimizer's symbolic kinematics)."""
    for f in config.frames:
        if f.name == frame:
            return f.parent_link
    for j in config.joints:
        if j.child_link == frame:
            return j.parent_link
    return frame


class GMRStyleIK:
    """Differential IK of position and orientation frame tasks, GMR / mink style."""

    def __init__(
        self,
        config: RobotConfig,
        frames: RobotSegmentFrames,
        settings: GMRStyleSettings | None = None,
    ) -> None:
        self.config = config
        self.settings = settings or GMRStyleSettings()
        self.kin = RobotKinematics(config)
        zero = np.zeros(config.num_joints)
        p0 = self.kin.frame_positions(zero, [*frames.starts, *frames.ends])
        self._length = np.linalg.norm(p0[8:] - p0[:8], axis=-1)  # (8,) robot segment lengths
        # Position tasks: per limb the middle and end point (elbow, wrist; knee, ankle).
        self.points = tuple(f for *_, a, b in LIMBS for f in (frames.ends[a], frames.ends[b]))
        # Each point is placed relative to its limb's root (the first segment's start).
        self.anchors = tuple(frames.starts[a] for *_, a, _ in LIMBS for _ in range(2))
        # Orientation tasks: the link carrying each mapped foot bone, and its alignment C
        # (G_robot = R_link · C, as in the optimizer's bone model).
        carrier_of = {b.end_frame: _carrier(config, b.end_frame) for b in config.bones}
        bones = {b.canonical: b for b in build_bones(config, carrier_of)}
        feet = [bones[name] for name in _FEET if name in bones]
        self.foot_links = tuple(b.carrier_link for b in feet)
        self.foot_joints = tuple(int(Joint[b.canonical]) for b in feet)
        if feet:
            ends = self.kin.frame_positions(zero, [b.end_frame for b in feet])
            starts = self.kin.frame_positions(zero, [b.start_frame for b in feet])
            rots = self.kin.frame_rotations(zero, list(self.foot_links))
            self._align = np.stack(
                [
                    alignment(b, e - s, r)
                    for b, e, s, r in zip(feet, ends, starts, rots, strict=True)
                ]
            )
        else:
            self._align = np.zeros((0, 3, 3))
        self._m0 = canonical_to_root(config)
        self._to_root = body_to_root(config)
        # Which joints move each task frame (orientation: the link's own joint too).
        names = [*self.points, *self.foot_links, *self.anchors]
        child_joint = {j.child_link: i for i, j in enumerate(config.joints)}
        self._moves = np.zeros((len(names), config.num_joints), dtype=bool)
        for k, name in enumerate(names):
            self._moves[k, sorted(joints_above(config, name))] = True
        for k, name in enumerate(self.foot_links, start=len(self.points)):
            if name in child_joint:
                self._moves[k, child_joint[name]] = True
        self._joint_links = [j.child_link for j in config.joints]
        self._axes = np.array(
            [np.asarray(j.axis, dtype=np.float64) / np.linalg.norm(j.axis) for j in config.joints]
        )

    # ------------------------------------------------------------------ targets
    def targets(self, positions: npt.ArrayLike, global_quats: npt.ArrayLike) -> GMRTargets:
        """Task targets from canonical global positions (T, 22, 3) and rotations (T, 22, 4)."""
        pos = np.asarray(positions, dtype=np.float64)
        glob = np.asarray(global_quats, dtype=np.float64)
        if pos.ndim != 3 or glob.shape[:2] != pos.shape[:2]:
            raise SolveError(f"positions (T, 22, 3) and rotations (T, 22, 4) must match: "
                             f"{pos.shape}, {glob.shape}")  # fmt: skip
        axes = trunk_frames_of_positions(pos).transpose(0, 2, 1)  # rows: the trunk frame
        m = np.einsum("ij,tjk->tik", self._to_root, axes)  # world → root frame, per frame
        out = []
        for root, mid, end, a, b in LIMBS:
            r, j, e = pos[:, Joint[root]], pos[:, Joint[mid]], pos[:, Joint[end]]
            du = np.einsum("tij,tj->ti", m, j - r)
            dl = np.einsum("tij,tj->ti", m, e - j)
            du /= np.maximum(np.linalg.norm(du, axis=-1, keepdims=True), 1e-12)
            dl /= np.maximum(np.linalg.norm(dl, axis=-1, keepdims=True), 1e-12)
            middle = self._length[a] * du
            out += [middle, middle + self._length[b] * dl]
        rots = np.zeros((pos.shape[0], len(self.foot_links), 3, 3))
        for k, (joint, c) in enumerate(zip(self.foot_joints, self._align, strict=True)):
            # R_link = G_h · Cᵀ with G_h = M_t · G_canonical · M0ᵀ (see optimize.bone_model).
            g = quat.to_matrix(glob[:, joint])
            rots[:, k] = m @ g @ self._m0.T @ c.T
        return GMRTargets(np.stack(out, axis=1), rots)

    # ------------------------------------------------------------------ IK
    def _step(
        self, q: FloatArray, target: GMRTargets, t: int, lo: FloatArray, hi: FloatArray
    ) -> FloatArray:
        """One differential-IK iteration from ``q`` within [lo, hi] (absolute bounds)."""
        st = self.settings
        cfg = self.config
        names = [*self.points, *self.foot_links]
        frames = self.kin.frame_transforms(q, [*names, *self.anchors, *self._joint_links])
        n, na, j = len(names), len(self.points), cfg.num_joints
        p, rot = frames[:n, :3, 3], frames[:n, :3, :3]
        anchor = frames[n : n + na, :3, 3]
        links = frames[n + na :]
        axes = np.einsum("jab,jb->ja", links[:, :3, :3], self._axes)  # joint axes, root frame
        origins = links[:, :3, 3]
        # Position tasks, all at once: (P, 3, J) Jacobians of point − limb root.
        jac = np.cross(axes[None], p[:na, None] - origins[None]).transpose(0, 2, 1)
        root = np.cross(axes[None], anchor[:, None] - origins[None]).transpose(0, 2, 1)
        jac = jac * self._moves[:na, None, :] - root * self._moves[n:, None, :]
        err = target.positions[t] - (p[:na] - anchor)  # (P, 3)
        # Orientation tasks: the joint axes that turn each foot link, rotation-vector errors.
        rjac = axes.T[None] * self._moves[na:n, None, :]  # (F, 3, J)
        turn = target.rotations[t] @ rot[na:].transpose(0, 2, 1)
        rerr = quat.to_rotation_vector(quat.from_matrix(turn))
        wj = np.concatenate([st.position_cost * jac, st.orientation_cost * rjac]).reshape(-1, j)
        we = np.concatenate([st.position_cost * err, st.orientation_cost * rerr])  # (K, 3)
        mu = st.lm_damping * float(np.sum(we * we))  # Σ_k lm · |W_k e_k|²
        h = wj.T @ wj + (st.damping + mu) * np.eye(j)
        c = -(wj.T @ we.ravel())
        wp = st.posture_cost
        h += wp * wp * np.eye(j)
        c -= wp * wp * (cfg.init_pose - q)
        dq = box_qp(h, c, lo - q, hi - q)
        return np.asarray(np.clip(q + dq, lo, hi), dtype=np.float64)

    def solve_clip(
        self, targets: GMRTargets, dt_s: float, q_start: npt.ArrayLike | None = None
    ) -> GMRResult:
        """Frame by frame from ``q_start`` (default: the init pose); frame 0 to convergence
        within the joint limits, later frames ``iterations`` steps within the velocity box."""
        cfg = self.config
        frames = targets.positions.shape[0]
        q = np.clip(
            np.asarray(cfg.init_pose if q_start is None else q_start, dtype=np.float64),
            cfg.lower,
            cfg.upper,
        )
        out = np.empty((frames, cfg.num_joints))
        step = cfg.max_velocity * dt_s
        t0 = time.perf_counter()
        for t in range(frames):
            if t == 0:
                lo, hi = cfg.lower, cfg.upper
                for _ in range(_SETTLE_MAX_ITER):
                    nxt = self._step(q, targets, 0, lo, hi)
                    done = float(np.max(np.abs(nxt - q))) < _SETTLE_TOL_RAD
                    q = nxt
                    if done:
                        break
            else:
                lo = np.maximum(cfg.lower, out[t - 1] - step)
                hi = np.minimum(cfg.upper, out[t - 1] + step)
                for _ in range(self.settings.iterations):
                    q = self._step(q, targets, t, lo, hi)
            out[t] = q
        return GMRResult(out, time.perf_counter() - t0)
