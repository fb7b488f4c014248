"""Per-frame optimizer targets, and the adapter from canonical rotations to them.

The optimizer works on what the evaluation scores: unit directions of the mapped bones (upper
arm, forearm, thigh, shin, torso, …) in the **trunk frame** of the retargeted pose
(:mod:`robot_retarget.skeleton.trunk`: up from the hip midpoint to the shoulder midpoint, left
along the hips) mapped into the robot root frame through its ``forward_axis`` / ``up_axis``.
The robot's trunk is that frame: the floating base
(:mod:`robot_retarget.pipeline.floating_base`) turns and tilts with it, so every limb stands in
the world where the pose put it. (Solving in an upright, heading-free frame and tilting the base
afterwards by the pelvis put OP3's thighs 14° off in the world on subjects 02/05/13; the Hips
joint's own rotation is no better a frame: a DAZ rig's Hips sit 10–15° off its torso.)
A bone's roll about itself comes in as a unit
normal (the canonical rest normal carried by the bone's global rotation), optional end
effectors as positions relative to the hips, scaled to the robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction
from robot_retarget.errors import SolveError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.geometry.quaternion_tables import product_table, rotation_table
from robot_retarget.optimize.formulation import RobotProblem
from robot_retarget.optimize.level_feet import (
    FootLevel,
    check_share,
    level_globals,
    rest_axes_of,
)
from robot_retarget.optimize.targets_graph import guard_ok, targets_function
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, Joint
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics
from robot_retarget.skeleton.tree_tables import pointer_jumps
from robot_retarget.skeleton.trunk import trunk_frame, trunk_frames_of_positions


@dataclass(frozen=True)
class FrameTargets:
    """Targets of one frame, robot root frame. B bones, E end effectors (robot config order).

    ``normals`` None: no orientation term. ``ee_positions`` None: no end-effector term;
    ``ee_weights`` (E,) scale each end effector (default 1). ``root_height_m``: height of the
    root above the ground when known (enables the feet-above-ground constraint).
    """

    directions: FloatArray  # (B, 3) unit
    normals: FloatArray | None = None  # (B, 3) unit
    ee_positions: FloatArray | None = None  # (E, 3) m
    ee_weights: FloatArray | None = None  # (E,)
    root_height_m: float | None = None
    # (3, 3) the trunk frame the targets are in (columns forward, left, up, canonical axes)
    trunk_frame: FloatArray | None = None


@dataclass(frozen=True)
class ClipTargets:
    """Targets of T frames, stacked: (T, B, 3), (T, B, 3), (T, E, 3), (T,)."""

    directions: FloatArray
    normals: FloatArray | None = None
    ee_positions: FloatArray | None = None
    ee_weights: FloatArray | None = None  # (E,), the same for every frame
    root_height_m: FloatArray | None = None
    trunk_frames: FloatArray | None = None  # (T, 3, 3)

    def __len__(self) -> int:
        return int(self.directions.shape[0])

    def frame(self, t: int) -> FrameTargets:
        return FrameTargets(
            directions=self.directions[t],
            normals=None if self.normals is None else self.normals[t],
            ee_positions=None if self.ee_positions is None else self.ee_positions[t],
            ee_weights=self.ee_weights,
            root_height_m=None if self.root_height_m is None else float(self.root_height_m[t]),
            trunk_frame=None if self.trunk_frames is None else self.trunk_frames[t],
        )

    def slice(self, start: int, stop: int) -> ClipTargets:
        def cut(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[start:stop]

        return ClipTargets(
            directions=self.directions[start:stop],
            normals=cut(self.normals),
            ee_positions=cut(self.ee_positions),
            ee_weights=self.ee_weights,
            root_height_m=cut(self.root_height_m),
            trunk_frames=cut(self.trunk_frames),
        )


def check_array(name: str, value: npt.ArrayLike, shape: tuple[int, ...]) -> FloatArray:
    """Float64 array of exactly ``shape`` with only finite entries, else SolveError."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape:
        raise SolveError(f"{name} must have shape {shape}, got {a.shape}; no command was produced")
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))
        raise SolveError(
            f"{name} contains NaN or infinite values (first at index "
            f"{tuple(int(i) for i in bad[0])}); "
            "no command was produced: check the upstream stage (network, motion source)"
        )
    return a


def check_dt(dt_s: float) -> float:
    """A time step in seconds as a finite positive float, else SolveError."""
    try:
        dt = float(dt_s)
    except (TypeError, ValueError):
        dt = math.nan
    if not (math.isfinite(dt) and dt > 0.0):
        raise SolveError(f"dt_s must be a finite positive number of seconds, got {dt_s!r}")
    return dt


def _unit_rows(v: FloatArray, fallback: FloatArray) -> FloatArray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = n > 1e-9
    return np.where(ok, v / np.where(ok, n, 1.0), fallback)


# A bone from the root to the top of the spine (Spine2, where the shoulders hang, or above)
# spans the whole trunk: its target is the torso line, hip midpoint → shoulder midpoint (the
# trunk frame's own up, and the torso eval-robot scores), not the performer's Hips → Neck
# joints. Those two lines meet at 0° on the canonical rest skeleton but 10–11° apart on the CMU
# rigs (their Hips joint sits behind the hip midpoint): Poppy's spine, following Hips → Neck,
# leaned its chest 8° off the performer's (ideal targets, CMU 02/05/13; 2.7° on the torso line).
# A robot with a rigid trunk (OP3) cannot move the bone, so its commands do not change.
_TRUNK_TOP = frozenset({"Spine2", "Neck", "Head"})


def spans_trunk(canonical: str, canonical_end: str) -> bool:
    """True for a bone from the root to the top of the spine: its target is the torso line."""
    return canonical == CANONICAL_JOINTS[0] and canonical_end in _TRUNK_TOP


def trunk_bones(problem: RobotProblem) -> list[int]:
    """Indices of the bones that span the trunk (:func:`spans_trunk`)."""
    return [k for k, b in enumerate(problem.bones) if spans_trunk(b.canonical, b.canonical_end)]


def _direct_bones(problem: RobotProblem) -> list[int]:
    """Bones whose start joint carries them (the end joint's parent): their rest direction is a
    fixed offset in the carrier's frame. The others (the trunk's torso line, a bone over several
    joints) keep the canonical rest normal."""
    return [
        k
        for k, b in enumerate(problem.bones)
        if b.carrier_joint == CANONICAL_JOINTS.index(b.canonical)
    ]


def rest_normals(problem: RobotProblem, rest_dirs: npt.ArrayLike, bones: list[int]) -> FloatArray:
    """(…, B, 3) each bone's rest normal in its carrier's frame (canonical axes), turned with the
    bone from the canonical rest direction onto ``rest_dirs`` (…, len(bones), 3), the
    skeleton's own, for ``bones``; the canonical rest normal for the others.

    The robot's normal at its zero pose is its bone's, turned the same way
    (:func:`.bone_model.alignment`), so a normal target is perpendicular to its direction
    target. Without the turn, OP3's foot (its ankle → toe line 4.65° steeper than the canonical
    foot's) had a roll target pitched 4.65° off its direction target, and the two terms pulled
    the foot between them."""
    to_c = problem.canonical_to_root.T
    normals = np.array([to_c @ b.rest_normal for b in problem.bones])
    axes = np.array([to_c @ b.rest_axis for b in problem.bones])
    dirs = np.asarray(rest_dirs, dtype=np.float64)
    out = np.array(np.broadcast_to(normals, (*dirs.shape[:-2], *normals.shape)))
    if bones:
        # A zero-length bone has no direction of its own: the canonical one.
        short = np.linalg.norm(dirs, axis=-1, keepdims=True) < 1e-9
        turn = quat.from_two_vectors(axes[bones], np.where(short, axes[bones], dirs))
        out[..., bones, :] = quat.rotate(turn, normals[bones])
    return out


def targets_from_rotations(
    problem: RobotProblem,
    skeleton: Skeleton,
    local_quats: npt.ArrayLike,
    *,
    root_pos: npt.ArrayLike | None = None,
    end_effectors: bool = False,
    scale: float = 1.0,
    level_feet: float = 0.0,
) -> ClipTargets:
    """Targets from canonical local rotations (T, 22, 4) on ``skeleton`` (canonical joints).

    ``skeleton`` should have the robot's proportions (the network's target skeleton);
    ``scale`` further scales end-effector offsets (m per skeleton unit); ``level_feet`` as
    :func:`targets_from_globals`. Runs the skeleton's FK, then :func:`targets_from_globals`.
    """
    if skeleton.names != CANONICAL_JOINTS:
        raise SolveError(
            "targets need a canonical skeleton (22 joints in canonical order); map the motion "
            f"onto robot_retarget.skeleton.canonical first (got {len(skeleton.names)} joints)"
        )
    q = np.asarray(local_quats, dtype=np.float64)
    if q.ndim != 3:
        raise SolveError(f"local rotations must be (T, 22, 4), got shape {q.shape}")
    q = check_array("local rotations", q, (q.shape[0], len(CANONICAL_JOINTS), 4))
    pos, glob = forward_kinematics(skeleton, q, root_pos)
    return targets_from_globals(
        problem, pos, glob, end_effectors=end_effectors, scale=scale, level_feet=level_feet
    )


def targets_from_globals(
    problem: RobotProblem,
    positions: npt.ArrayLike,
    global_quats: npt.ArrayLike,
    *,
    end_effectors: bool = False,
    scale: float = 1.0,
    level_feet: float = 0.0,
) -> ClipTargets:
    """Targets from canonical global positions (T, 22, 3) and rotations (T, 22, 4).

    For sources that already have them (a motion's ``positions()`` / ``global_quats()``).
    ``level_feet``: the share of each foot's roll about its long axis left out
    (:mod:`.level_feet`; the robot's ``retarget.level_feet``; 0: the rotations as given).
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3:
        raise SolveError(f"positions must be (T, 22, 3), got shape {pos.shape}")
    frames = pos.shape[0]
    pos = check_array("positions", pos, (frames, len(CANONICAL_JOINTS), 3))
    glob = check_array("global rotations", global_quats, (frames, len(CANONICAL_JOINTS), 4))
    if check_share(level_feet) > 0.0:
        glob = level_globals(FootLevel.of_axes(rest_axes_of(pos, glob), level_feet), glob)
    body = trunk_frames_of_positions(pos)  # (T, 3, 3) canonical
    # M_t = F · B_tᵀ: canonical → robot root frame, per frame.
    m = np.einsum("ij,tkj->tik", problem.body_to_root, body)
    starts = [CANONICAL_JOINTS.index(b.canonical) for b in problem.bones]
    ends = [CANONICAL_JOINTS.index(b.canonical_end) for b in problem.bones]
    carriers = [b.carrier_joint for b in problem.bones]
    rest_axes = np.array([b.rest_axis for b in problem.bones])
    vectors = pos[:, ends] - pos[:, starts]
    hips = 0.5 * (pos[:, Joint.LeftUpLeg] + pos[:, Joint.RightUpLeg])
    shoulders = 0.5 * (pos[:, Joint.LeftArm] + pos[:, Joint.RightArm])
    vectors[:, trunk_bones(problem)] = (shoulders - hips)[:, None]
    dirs = _unit_rows(np.einsum("tij,tbj->tbi", m, vectors), rest_axes)
    # Each bone's rest direction in its carrier's frame, as this skeleton has it.
    direct = _direct_bones(problem)
    own = quat.rotate(
        quat.conjugate(glob[:, [carriers[k] for k in direct]]),
        pos[:, [ends[k] for k in direct]] - pos[:, [starts[k] for k in direct]],
    )
    normals_c = rest_normals(problem, own, direct)  # (T, B, 3)
    carried = quat.rotate(glob[:, carriers], normals_c)  # (T, B, 3) canonical
    normals = _unit_rows(np.einsum("tij,tbj->tbi", m, carried), rest_axes)
    ee = None
    if end_effectors and problem.ee_frames:
        idx = [CANONICAL_JOINTS.index(name) for name, _ in problem.ee_frames]
        rel = (pos[:, idx] - hips[:, None]) * scale
        ee = problem.hip_center + np.einsum("tij,tej->tei", m, rel)
    return ClipTargets(directions=dirs, normals=normals, ee_positions=ee, trunk_frames=body)


class FrameTargetBuilder:
    """:func:`targets_from_rotations` for one frame at a time (the live path), same numbers.

    Everything that depends only on the robot and ``skeleton`` is computed here once. Per frame,
    global rotations come from pointer jumping (``G_n ← G_anc(n) ⊗ G_n``, log₂ depth rounds of
    one (23, 4) product each) and only the vectors the targets use are rotated: each bone offset
    once, then bone directions and hip axis as fixed sums of them (the root position cancels).
    """

    def __init__(
        self,
        problem: RobotProblem,
        skeleton: Skeleton,
        *,
        end_effectors: bool = False,
        scale: float = 1.0,
        level_feet: float = 0.0,
    ) -> None:
        if skeleton.names != CANONICAL_JOINTS:
            raise SolveError(
                "targets need a canonical skeleton (22 joints in canonical order); map the "
                "motion onto robot_retarget.skeleton.canonical first "
                f"(got {len(skeleton.names)} joints)"
            )
        j = len(CANONICAL_JOINTS)
        parents = skeleton.parents
        # Row j is a sentinel "parent of the root" that holds the identity.
        jumps = pointer_jumps(parents)
        parent = jumps[0]
        self._jumps = [np.array(a, dtype=np.int64) for a in jumps]
        self._glob = np.zeros((j + 1, 4))
        self._glob[j, 0] = 1.0
        # chain[n, k] = 1 when bone k (joint k's offset, k ≥ 1) lies on the root → n path.
        chain = np.zeros((j, j - 1))
        for n in range(j):
            k = n
            while k > 0:
                chain[n, k - 1] = 1.0
                k = parents[k]
        bones = problem.bones
        starts = [CANONICAL_JOINTS.index(b.canonical) for b in bones]
        ends = [CANONICAL_JOINTS.index(b.canonical_end) for b in bones]
        nb = len(bones)
        hips = 0.5 * (chain[Joint.LeftUpLeg] + chain[Joint.RightUpLeg])
        shoulders = 0.5 * (chain[Joint.LeftArm] + chain[Joint.RightArm])
        bone_rows = chain[ends] - chain[starts]
        bone_rows[trunk_bones(problem)] = shoulders - hips
        rows = [
            bone_rows,
            (chain[Joint.LeftUpLeg] - chain[Joint.RightUpLeg])[None],  # hip axis
            (shoulders - hips)[None],  # trunk
        ]
        self._ee = end_effectors and bool(problem.ee_frames)
        if self._ee:
            idx = [CANONICAL_JOINTS.index(name) for name, _ in problem.ee_frames]
            rows.append((chain[idx] - hips) * scale)
        self._sums = np.concatenate(rows)  # bone vectors → (B + 1 + E, 3) canonical vectors
        # Rotate each bone offset by its parent's global rotation, each rest normal by its
        # carrier's, in one batched product.
        self._rot_index = np.array(
            [parent[i] for i in range(1, j)] + [b.carrier_joint for b in bones], dtype=np.int64
        )
        direct = _direct_bones(problem)
        normals_c = rest_normals(problem, skeleton.offsets[[ends[k] for k in direct]], direct)
        self._vectors = np.concatenate([skeleton.offsets[1:], normals_c])[:, :, None]
        self._num_offsets = j - 1
        self._num_bones = nb
        self._fallback = np.concatenate([np.array([b.rest_axis for b in bones])] * 2)
        self._body_to_root = problem.body_to_root
        self._hip_center = problem.hip_center
        self._mul = product_table()
        self._rot = rotation_table()
        self._eye = np.eye(3).ravel()
        share = check_share(level_feet)
        self._level = FootLevel.of_skeleton(skeleton.offsets, share) if share > 0.0 else None
        # The same arithmetic as one casadi call (targets_graph); __call__ takes the numpy
        # path below only for frames the graph's guard flags (degenerate vectors).
        self._graph = CompiledFunction(
            targets_function(
                parents,
                self._rot_index.tolist(),
                self._vectors[:, :, 0],
                self._sums,
                nb,
                self._body_to_root,
                self._hip_center if self._ee else None,
                share,
                None if self._level is None else self._level.rest_axes,
            )
        )
        self._q_in = self._graph.args[0].reshape(j, 4)
        dirs, normals, ee, trunk, self._guard = self._graph.res
        self._outputs = (dirs.reshape(nb, 3), normals.reshape(nb, 3), ee.reshape(-1, 3))
        self._trunk = trunk.reshape(3, 3)

    @property
    def graph(self) -> ca.Function:
        """The targets as one SX function (:func:`.targets_graph.targets_function`)."""
        return self._graph.function

    @property
    def end_effectors(self) -> bool:
        """True when the targets carry end-effector positions."""
        return self._ee

    def __call__(self, local_quats: npt.ArrayLike) -> FrameTargets:
        """Targets of one frame of canonical local rotations (22, 4) (unit)."""
        q = check_array("local rotations", local_quats, (len(CANONICAL_JOINTS), 4))
        self._q_in[...] = q
        self._graph()
        if not guard_ok(self._guard):
            return self._numpy_call(q)
        dirs, normals, ee = self._outputs
        return FrameTargets(
            directions=dirs.copy(),
            normals=normals.copy(),
            ee_positions=ee.copy() if self._ee else None,
            trunk_frame=self._trunk.copy(),
        )

    def _numpy_call(self, q: FloatArray) -> FrameTargets:
        """The targets in numpy, with the fallbacks of degenerate frames."""
        g = self._glob
        g[:-1] = q
        mul = self._mul
        for anc in self._jumps:
            g = (g[anc][:, :, None] * g[:, None, :]).reshape(-1, 16) @ mul
        if self._level is not None:
            g[:-1] = level_globals(self._level, g[:-1])
        sel = g[self._rot_index]
        mats = (sel[:, :, None] * sel[:, None, :]).reshape(-1, 16) @ self._rot + self._eye
        rotated = (mats.reshape(-1, 3, 3) @ self._vectors)[:, :, 0]
        no, nb = self._num_offsets, self._num_bones
        sums = self._sums @ rotated[:no]  # bone directions, hip axis, trunk, end effectors
        trunk = trunk_frame(sums[nb], sums[nb + 1])
        # Trunk frame (forward, left, up) as rows, then canonical → robot root.
        m = self._body_to_root @ trunk.T
        vecs = np.concatenate([sums[:nb], rotated[no:]]) @ m.T
        norms = np.sqrt(np.einsum("ij,ij->i", vecs, vecs))[:, None]
        if norms.min() > 1e-9:
            vecs /= norms
        else:
            vecs = _unit_rows(vecs, self._fallback)
        ee = None
        if self._ee:
            ee = self._hip_center + sums[nb + 2 :] @ m.T
        return FrameTargets(
            directions=vecs[:nb], normals=vecs[nb:], ee_positions=ee, trunk_frame=trunk
        )
