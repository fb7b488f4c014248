"""The residual model's per-frame geometry as three compiled SX stages (see
:mod:`robot_retarget.runtime.residual` for how the step chains them with its dense layers).

- ``features(q, past) → (feats, rel, past_next)``: the denoiser's input per joint: the rotation
  vectors from the current to each past rotation ``log(q_t⁻¹ ⊗ q_t−k)`` (×10), their norms
  (×10), the rotation's own angle and the joint's one-hot code (the first layer's per-joint
  bias), then the history shifted by one frame.
- ``pose(q, rel, weights, offsets) → (q_den, x)``: the denoised rotations
  ``q ⊗ exp(Σ_k w_k·rel_k)`` (the root untouched), and the correction network's input from
  them: root-relative joint positions by forward kinematics on ``offsets``, then each joint's
  first two rotation-matrix columns (6D), then a constant 1 (the first layer's bias column).
- ``output(q_den, u, yaw, cap) → q``: ``q_den ⊗ exp(cap·tanh(u/cap))``, normalised, with the
  heading ``yaw`` put back on the root.
- ``output_lock(q_den, u, yaw, cap, *lock inputs) → (q, lock state)``: the same output with the
  foot lock (:mod:`robot_retarget.runtime.foot_lock_graph`) applied to its legs, in one call
  (the lock's inputs but its ``q_out``, which is this output).

Every array is row-major: (J, 4) quaternions, (J, K, 4) history, (J, 3) vectors. The graphs
depend only on the joint tree and the history length, not on a performer or the weights
(those are inputs), so one compiled build serves every clip.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca

from robot_retarget.casadi_jit import compile_graph
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.runtime.foot_lock_graph import LEG_JOINTS, foot_lock_graph

REL_SCALE = 10.0  # as robot_retarget.nn.models.residual


def features_graph(num_joints: int, history: int) -> tuple[list[ca.SX], list[ca.SX]]:
    j, k = num_joints, history
    q = ca.SX.sym("q", 4 * j)
    past = ca.SX.sym("past", 4 * j * k)
    feats: list[ca.SX] = []
    rel: list[ca.SX] = []
    past_next: list[ca.SX] = []
    for n in range(j):
        qn = sq.quat_at(q, n)
        inv = sq.conj(qn)
        vecs = [sq.rotvec(sq.qmul(inv, sq.quat_at(past, n * k + m))) for m in range(k)]
        for v in vecs:
            feats.extend(REL_SCALE * c for c in v)
            rel.extend(v)
        feats.extend(REL_SCALE * sq.norm(v) for v in vecs)
        feats.append(sq.angle(qn))
        feats.extend(ca.SX(1.0 if m == n else 0.0) for m in range(j))
        past_next.extend(qn)
        for m in range(k - 1):
            past_next.extend(sq.quat_at(past, n * k + m))
    return [q, past], [ca.vertcat(*feats), ca.vertcat(*rel), ca.vertcat(*past_next)]


def pose_graph(parents: tuple[int, ...], history: int) -> tuple[list[ca.SX], list[ca.SX]]:
    j, k = len(parents), history
    q = ca.SX.sym("q", 4 * j)
    rel = ca.SX.sym("rel", 3 * j * k)
    weights = ca.SX.sym("weights", j * k)
    offsets = ca.SX.sym("offsets", 3 * j)
    q_den: list[sq.Quat] = [sq.quat_at(q, 0)]
    for n in range(1, j):
        corr = [
            sum((weights[n * k + m] * rel[3 * (n * k + m) + c] for m in range(k)), ca.SX(0.0))
            for c in range(3)
        ]
        q_den.append(sq.qmul(sq.quat_at(q, n), sq.from_rotvec(corr)))
    local = [sq.matrix(qn) for qn in q_den]
    glob: list[sq.Mat] = []
    pos: list[sq.Vec] = []
    for n, p in enumerate(parents):
        if p < 0:
            glob.append(local[n])
            pos.append((ca.SX(0.0), ca.SX(0.0), ca.SX(0.0)))
            continue
        glob.append(sq.matmul(glob[p], local[n]))
        bone = sq.rotate(glob[p], sq.vec_at(offsets, n))
        pos.append((pos[p][0] + bone[0], pos[p][1] + bone[1], pos[p][2] + bone[2]))
    x = [c for v in pos for c in v]
    for m in local:  # column 0, then column 1 of each joint's local matrix
        x.extend((m[0], m[3], m[6], m[1], m[4], m[7]))
    x.append(ca.SX(1.0))
    den = [c for qn in q_den for c in qn]
    return [q, rel, weights, offsets], [ca.vertcat(*den), ca.vertcat(*x)]


def output_graph(num_joints: int) -> tuple[list[ca.SX], list[ca.SX]]:
    q_den = ca.SX.sym("q_den", 4 * num_joints)
    u = ca.SX.sym("u", 3 * num_joints)
    yaw = ca.SX.sym("yaw")
    cap = ca.SX.sym("cap")
    out: list[ca.SX] = []
    for n in range(num_joints):
        ux, uy, uz = sq.vec_at(u, n)
        delta = sq.from_rotvec(
            (cap * ca.tanh(ux / cap), cap * ca.tanh(uy / cap), cap * ca.tanh(uz / cap))
        )
        qb = sq.normalize(sq.qmul(sq.quat_at(q_den, n), delta))
        out.extend(sq.with_heading(qb, yaw) if n == 0 else qb)
    return [q_den, u, yaw, cap], [ca.vertcat(*out)]


def output_lock_graph(num_joints: int) -> tuple[list[ca.SX], list[ca.SX]]:
    out_inputs, (out,) = output_graph(num_joints)
    lock_inputs, (legs, state_next) = foot_lock_graph()
    q_out = lock_inputs[3]
    legs, state_next = ca.substitute([legs, state_next], [q_out], [out])
    rows = [out[i] for i in range(4 * num_joints)]
    for k, joint in enumerate(LEG_JOINTS):
        rows[4 * joint : 4 * joint + 4] = [legs[4 * k + c] for c in range(4)]
    inputs = out_inputs + [x for x in lock_inputs if x is not q_out]
    return inputs, [ca.vertcat(*rows), state_next]


@lru_cache(maxsize=4)
def output_lock_function(num_joints: int, *, jit: bool = True) -> ca.Function:
    """The output stage with the foot lock, compiled once per process (and machine)."""
    return compile_graph("residual_output_lock", *output_lock_graph(num_joints), jit=jit)


@lru_cache(maxsize=4)
def residual_stages(
    parents: tuple[int, ...], history: int, *, jit: bool = True
) -> tuple[ca.Function, ca.Function, ca.Function]:
    """(features, pose, output) for a joint tree and history length, compiled once per
    process (and once per machine: the build is cached on disk)."""
    j = len(parents)
    return (
        compile_graph("residual_features", *features_graph(j, history), jit=jit),
        compile_graph("residual_pose", *pose_graph(parents, history), jit=jit),
        compile_graph("residual_output", *output_graph(j), jit=jit),
    )
