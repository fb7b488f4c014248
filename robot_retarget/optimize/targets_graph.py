"""One frame's optimizer targets as a single SX function of its canonical local rotations.

:class:`robot_retarget.optimize.targets.FrameTargetBuilder`'s arithmetic (global rotations
down the tree, bone offsets and rest normals rotated, bone vectors as fixed sums of them, the
trunk frame, the map into the robot root frame, unit rows) in one casadi call instead of ~25
numpy calls on (22, 4) arrays. The robot's and skeleton's constants are folded into the graph.
It runs in casadi's virtual machine (≈ 2k instructions, a few µs), not compiled: every robot
config (tests build dozens) would otherwise cost a C compile.

The graph assumes a regular frame. Its last output holds the three norms the numpy path
guards (trunk, hip axis off the trunk, smallest target vector): where one is at most
:data:`GUARD_EPS` the caller takes the numpy path and its fallbacks.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import memoized_graph
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.optimize.level_feet import FootLevel, level_twists_sx

GUARD_EPS = 1e-9


def _rotation(q: sq.Quat) -> sq.Mat:
    """I + the quadratic form of ``quat.rotate`` (rotation_table's convention, any q)."""
    w, x, y, z = q
    return (
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    )


def _linear(m: FloatArray, v: Sequence[ca.SX]) -> list[ca.SX]:
    """``m @ v`` for a constant matrix, zero entries left out of the graph."""
    return [
        sum((float(m[i, k]) * v[k] for k in range(m.shape[1]) if m[i, k] != 0.0), ca.SX(0.0))
        for i in range(m.shape[0])
    ]


@memoized_graph
def targets_function(
    parents: Sequence[int],
    rot_index: Sequence[int],
    vectors: FloatArray,
    sums: FloatArray,
    num_bones: int,
    body_to_root: FloatArray,
    hip_center: FloatArray | None,
    level_feet: float = 0.0,
    foot_axes: FloatArray | None = None,
) -> ca.Function:
    """``q (J·4) → (directions B·3, normals B·3, ee E·3, trunk 3·3, guard 3)``, row-major.

    ``rot_index`` names the joint whose global rotation turns each row of ``vectors`` (the
    bone offsets of joints 1…J−1, then the rest normals); ``sums`` (B + 2 + E, J − 1) adds
    rotated offsets up into bone vectors, the hip axis, the trunk and the end effectors
    (relative to the hips); ``hip_center`` None: no end effectors. ``level_feet`` > 0 with the
    feet's rest axes ``foot_axes`` (2, 3): the feet turned level (:mod:`.level_feet`).
    """
    j = len(parents)
    q = ca.SX.sym("q", 4 * j)
    glob: list[sq.Quat] = []
    for n, p in enumerate(parents):
        qn = sq.quat_at(q, n)
        glob.append(qn if p < 0 else sq.qmul(glob[p], qn))
    if level_feet > 0.0 and foot_axes is not None:
        level = FootLevel.of_axes(foot_axes, level_feet)
        twists = level_twists_sx(level, [glob[f] for f in level.feet])
        for twist, joints in zip(twists, level.turned, strict=True):
            for n in joints:
                glob[n] = sq.qmul(twist, glob[n])
    rotated: list[sq.Vec] = []
    for row, idx in enumerate(rot_index):
        v = vectors[row]
        rotated.append(sq.rotate(_rotation(glob[idx]), (v[0], v[1], v[2])))
    no = j - 1
    comps = [_linear(sums, [r[c] for r in rotated[:no]]) for c in range(3)]
    summed: list[sq.Vec] = [(comps[0][i], comps[1][i], comps[2][i]) for i in range(len(sums))]
    nb = num_bones
    hip_axis, trunk = summed[nb], summed[nb + 1]
    up, trunk_norm = sq.unit(trunk)
    left, left_norm = sq.unit(sq.reject(hip_axis, up))
    left, _ = sq.unit(sq.reject(left, up))  # a second pass, as skeleton.trunk.trunk_frame
    fwd = sq.cross(left, up)
    frame = [c for i in range(3) for c in (fwd[i], left[i], up[i])]  # row-major, columns f, l, u
    # M = body_to_root · frameᵀ maps canonical vectors into the robot root frame.
    m = [
        sum((float(body_to_root[r, k]) * frame[3 * c + k] for k in range(3)), ca.SX(0.0))
        for r in range(3)
        for c in range(3)
    ]

    def to_root(v: sq.Vec) -> sq.Vec:
        return sq.rotate(m, v)

    vecs = [to_root(v) for v in summed[:nb]] + [to_root(v) for v in rotated[no:]]
    units = [sq.unit(v) for v in vecs]
    smallest = ca.mmin(ca.vertcat(*(n for _, n in units)))
    dirs = [c for u, _ in units[:nb] for c in u]
    normals = [c for u, _ in units[nb:] for c in u]
    ee: list[ca.SX] = []
    if hip_center is not None:
        for v in summed[nb + 2 :]:
            r = to_root(v)
            ee.extend(float(hip_center[c]) + r[c] for c in range(3))
    return ca.Function(
        "frame_targets",
        [q],
        [
            ca.vertcat(*dirs),
            ca.vertcat(*normals),
            ca.vertcat(*ee) if ee else ca.SX(0, 1),
            ca.vertcat(*frame),
            ca.vertcat(trunk_norm, left_norm, smallest),
        ],
    )


def guard_ok(guard: FloatArray) -> bool:
    # Three numbers: Python floats beat a numpy reduction's call overhead; NaN fails.
    return all(g > GUARD_EPS for g in guard.tolist())
