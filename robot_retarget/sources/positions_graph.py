""":class:`robot_retarget.sources.from_positions.PositionsToRotations` as one CasADi SX function.

The numpy solve walks the 22 joints in Python with a handful of small array calls each (≈ 1 ms
per frame under load: the largest stage of a live position stream). The same arithmetic —
triads for the Hips and Spine2, the shortest arc for every other joint with one child, rotation
matrices down the tree, Shepperd's matrix → quaternion with w ≥ 0 — is one SX graph here, with
the performer's rest directions and frames folded in. It runs in casadi's virtual machine (a
few thousand instructions): one graph per performer skeleton, so no C compile.

The graph assumes a regular frame. Its second output is the smallest *margin* of the numpy
path's branch tests (a bone longer than its ε, a triad's axes longer than theirs, a shortest arc
short of a half turn): where it is not positive, the caller takes the numpy path.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import memoized_graph
from robot_retarget.geometry import symbolic_quaternion as sq


def _frame(primary: sq.Vec, secondary: sq.Vec) -> tuple[sq.Mat, ca.SX, ca.SX]:
    """Columns e1 = primary/|primary|, e2 = secondary made orthogonal, e3 = e1 × e2; and the
    two norms the numpy ``_frame`` tests."""
    e1, n1 = sq.unit(primary)
    e2, n2 = sq.unit(sq.reject(secondary, e1))
    e3 = sq.cross(e1, e2)
    return (e1[0], e2[0], e3[0], e1[1], e2[1], e3[1], e1[2], e2[2], e3[2]), n1, n2


def _shortest_arc(a: FloatArray, b: sq.Vec) -> tuple[sq.Mat, ca.SX]:
    """I + K + K²/(1 + c) for unit a (constant) onto unit b, and c = a · b."""
    a_const = tuple(ca.SX(float(x)) for x in a)
    c = sq.dot(a_const, b)
    vx, vy, vz = sq.cross(a_const, b)
    k: sq.Mat = (ca.SX(0.0), -vz, vy, vz, ca.SX(0.0), -vx, -vy, vx, ca.SX(0.0))
    kk = sq.matmul(k, k)
    inv = 1.0 / (1.0 + c)
    return tuple(sq.IDENTITY[i] + k[i] + kk[i] * inv for i in range(9)), c


def _quaternion(m: sq.Mat) -> sq.Quat:
    """``quat.from_matrix``: Shepperd's largest pivot (the first on ties), normalised, w ≥ 0."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    cands = (
        (1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01),
        (m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20),
        (m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21),
        (m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22),
    )
    pivots = (cands[0][0], cands[1][1], cands[2][2], cands[3][3])
    q: sq.Quat = cands[0]
    best = pivots[0]
    for cand, pivot in zip(cands[1:], pivots[1:], strict=True):
        take = pivot > best
        q = tuple(ca.if_else(take, cand[i], q[i]) for i in range(4))
        best = ca.fmax(best, pivot)
    q = sq.normalize(q)
    sign = ca.if_else(q[0] < 0.0, -1.0, 1.0)
    return tuple(sign * c for c in q)


@memoized_graph
def positions_function(
    parents: Sequence[int],
    children: Mapping[int, int],
    rest_dirs: Mapping[int, FloatArray | None],
    triads: Mapping[int, tuple[int, tuple[int, int]]],
    rest_frames: Mapping[int, FloatArray | None],
    eps: float,
) -> ca.Function:
    """``p (J·3) → (local quaternions J·4, margin)``, row-major; the arguments are
    PositionsToRotations' per-skeleton tables."""
    j_count = len(parents)
    p = ca.SX.sym("p", 3 * j_count)
    pts = [(p[3 * j], p[3 * j + 1], p[3 * j + 2]) for j in range(j_count)]
    glob: list[sq.Mat] = []
    local: list[sq.Mat] = []
    margins: list[ca.SX] = []
    for j, parent in enumerate(parents):
        g_parent = sq.IDENTITY if parent < 0 else glob[parent]
        if j in triads:
            prim, (left, right) = triads[j]
            rest = rest_frames[j]
            cur, n1, n2 = _frame(sq.sub(pts[prim], pts[j]), sq.sub(pts[left], pts[right]))
            margins += [n1 - eps, n2 - eps]
            if rest is None:
                g = g_parent
            else:
                rest_t = tuple(ca.SX(float(x)) for x in rest.T.ravel())
                g = sq.matmul(cur, rest_t)
            glob.append(g)
            local.append(sq.matmul(sq.transpose(g_parent), g))
            continue
        loc = sq.IDENTITY
        child = children.get(j)
        rest_dir = rest_dirs.get(j)
        if child is not None and rest_dir is not None:
            d_cur = sq.rotate(sq.transpose(g_parent), sq.sub(pts[child], pts[j]))
            direction, norm = sq.unit(d_cur)
            margins.append(norm - eps)
            loc, c = _shortest_arc(rest_dir, direction)
            margins.append(c - (-1.0 + 1e-9))
        local.append(loc)
        glob.append(sq.matmul(g_parent, loc))
    quats = [c for m in local for c in _quaternion(m)]
    margin = ca.mmin(ca.vertcat(*margins)) if margins else ca.SX(np.inf)
    return ca.Function("positions_to_rotations", [p], [ca.vertcat(*quats), margin])
