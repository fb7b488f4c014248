"""TDCN's per-frame geometry as two compiled SX stages (see
:class:`robot_retarget.runtime.tdcn.FastTDCNRetargeter` for how its step chains them with the
ring-buffered convolutions).

- ``inputs(q, vel, offsets, mean, std) → (x, q_unit)``: unit rotations (a near-zero quaternion
  becomes the identity, as :func:`robot_retarget.runtime.frame.unit_quaternions`), then the
  network's standardised input ``[p, q, v]``: root-relative joint positions by forward
  kinematics on ``offsets``, the rotations with w ≥ 0, the root movement.
- ``outputs(raw, q, vel, heights) → (q_b, v_b)``: the head's rotations made unit and, for a
  residual TDCN, composed after the input's (``q ⊗ Δq``, unit again); the root movement
  ``(v / h_src + Δv) · h_tgt`` and turning rate ``ω + Δω``.

The graphs depend only on the joint tree and the residual flag, not on a performer or the
weights (those are inputs), so one compiled build serves every clip. Their numpy counterparts
(:mod:`robot_retarget.runtime.tdcn`'s ``_Head`` and ``_features_of_clip``) run the clip path;
the two agree to rounding (tests/runtime).
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca

from robot_retarget.casadi_jit import compile_graph
from robot_retarget.geometry import symbolic_quaternion as sq


def inputs_graph(parents: tuple[int, ...]) -> tuple[list[ca.SX], list[ca.SX]]:
    j = len(parents)
    q = ca.SX.sym("q", 4 * j)
    vel = ca.SX.sym("vel", 4)
    offsets = ca.SX.sym("offsets", 3 * j)
    size = 3 * j + 4 * j + 4
    mean = ca.SX.sym("mean", size)
    std = ca.SX.sym("std", size)
    units = [sq.unit_or_identity(sq.quat_at(q, n)) for n in range(j)]
    glob: list[sq.Mat] = []
    pos: list[sq.Vec] = []
    for n, p in enumerate(parents):
        local = sq.matrix(units[n])
        if p < 0:
            glob.append(local)
            pos.append((ca.SX(0.0), ca.SX(0.0), ca.SX(0.0)))
            continue
        glob.append(sq.matmul(glob[p], local))
        pos.append(sq.add(pos[p], sq.rotate(glob[p], sq.vec_at(offsets, n))))
    raw = [c for v in pos for c in v]
    for u in units:  # w ≥ 0: the sign the network was trained on
        flip = ca.if_else(u[0] < 0.0, -1.0, 1.0)
        raw.extend(flip * c for c in u)
    raw.extend(vel[i] for i in range(4))
    x = [(raw[i] - mean[i]) / std[i] for i in range(size)]
    q_unit = [c for u in units for c in u]
    return [q, vel, offsets, mean, std], [ca.vertcat(*x), ca.vertcat(*q_unit)]


def outputs_graph(num_joints: int, residual: bool) -> tuple[list[ca.SX], list[ca.SX]]:
    j = num_joints
    raw = ca.SX.sym("raw", 4 * j + 4)
    q = ca.SX.sym("q", 4 * j)
    vel = ca.SX.sym("vel", 4)
    heights = ca.SX.sym("heights", 2)  # source, target (m)
    out: list[ca.SX] = []
    for n in range(j):
        dq = sq.unit_or_identity(sq.quat_at(raw, n))
        out.extend(sq.unit_or_identity(sq.qmul(sq.quat_at(q, n), dq)) if residual else dq)
    dv = [raw[4 * j + i] for i in range(4)]
    move = [(vel[i] / heights[0] + dv[i]) * heights[1] for i in range(3)]
    move.append(vel[3] + dv[3])
    return [raw, q, vel, heights], [ca.vertcat(*out), ca.vertcat(*move)]


@lru_cache(maxsize=4)
def tdcn_stages(
    parents: tuple[int, ...], residual: bool, *, jit: bool = True
) -> tuple[ca.Function, ca.Function]:
    """(inputs, outputs) for a joint tree, compiled once per process (and once per machine:
    the build is cached on disk)."""
    kind = "residual" if residual else "direct"
    return (
        compile_graph("tdcn_inputs", *inputs_graph(parents), jit=jit),
        compile_graph(f"tdcn_outputs_{kind}", *outputs_graph(len(parents), residual), jit=jit),
    )
