"""The keypoint model's stream step around its dense layers, as compiled SX graphs: two calls
instead of about a hundred small numpy calls (robot_retarget.casadi_jit says why). The dense
layers stay in numpy (BLAS).

- :func:`features_function`: a camera frame's keypoints and the normaliser's state → the
  features of the image and of its left-right mirror (robot_retarget.keypoints.normalize run
  on both; the mirror's are the image's, keypoints swapped and x negated, exactly, so its
  state is the image's) and the next state.
- :func:`answer_function`: each model's head outputs for the image and its mirror (22 6D
  rotations each) → the local rotations (runtime.agnostic2d.rotation_6d_to_quat; with several
  models, each image's answers averaged over them, mean_rotation; then average_with_mirrored).

Keypoints enter as values with NaN replaced by 0 and a 0/1 mask; the normaliser's NaN states
("not set yet") as a value and a 0/1 flag. The numpy code is the reference: the tests hold
the two to 1e-9 on whole streams, missing points and all.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from robot_retarget.casadi_jit import compile_graph, memoized_graph
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.keypoints import normalize as nz
from robot_retarget.keypoints.coco17 import FLIP_PAIRS, NUM_KEYPOINTS, Coco
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS
from robot_retarget.skeleton.mirror import JOINT_MIRROR, swap_index

STATE_SIZE = 5
"""The normaliser's state: centre x, y, whether a centre is set, the scale, whether it is set."""
_J = len(CANONICAL_JOINTS)
_KEYPOINT_MIRROR = swap_index(list(FLIP_PAIRS), NUM_KEYPOINTS)
_FAR = 1e30  # stands for ±inf in the bounding box's max / min over the points seen


def initial_state() -> np.ndarray:
    """The normaliser's state before any frame (nothing set)."""
    return np.zeros(STATE_SIZE)


@memoized_graph
def features_function() -> ca.Function:
    """``(xy 17·2, seen 17, state 5) → (features 2·51, state 5)``: the features of the image
    (first 51) and of its mirror (next 51), as KeypointNormalizer.step on both."""
    xy = ca.SX.sym("xy", 2 * NUM_KEYPOINTS)
    seen = ca.SX.sym("seen", NUM_KEYPOINTS)
    state = ca.SX.sym("state", STATE_SIZE)
    v = [seen[k] for k in range(NUM_KEYPOINTS)]
    p = [(v[k] * xy[2 * k], v[k] * xy[2 * k + 1]) for k in range(NUM_KEYPOINTS)]
    lh, rh, ls, rs = Coco.left_hip, Coco.right_hip, Coco.left_shoulder, Coco.right_shoulder
    hips_seen, shoulders_seen = v[lh] * v[rh], v[ls] * v[rs]
    hip_mid = [0.5 * (p[lh][a] + p[rh][a]) for a in (0, 1)]
    shoulder_mid = [0.5 * (p[ls][a] + p[rs][a]) for a in (0, 1)]
    count = sum(v[1:], v[0])
    any_seen = count > 0.0
    mean_seen = [sum((q[a] for q in p[1:]), p[0][a]) / ca.fmax(count, 1.0) for a in (0, 1)]
    # Centre: mid-hip when seen, else the last centre, else the mean of what is seen.
    has_centre = state[2] > 0.5
    centre = [ca.if_else(hips_seen > 0.5, hip_mid[a], state[a]) for a in (0, 1)]
    known = ca.logic_or(hips_seen > 0.5, has_centre)
    first = ca.logic_and(ca.logic_not(known), any_seen)
    centre = [ca.if_else(first, mean_seen[a], centre[a]) for a in (0, 1)]
    centre_set = ca.logic_or(known, first)
    # Scale: running torso length; the bounding box until a torso was seen.
    dx, dy = shoulder_mid[0] - hip_mid[0], shoulder_mid[1] - hip_mid[1]
    torso = ca.sqrt(dx * dx + dy * dy)
    measured = ca.logic_and(hips_seen * shoulders_seen > 0.5, torso > 1.0)
    top = _max([ca.if_else(v[k] > 0.5, p[k][1], -_FAR) for k in range(NUM_KEYPOINTS)])
    bottom = _min([ca.if_else(v[k] > 0.5, p[k][1], _FAR) for k in range(NUM_KEYPOINTS)])
    box = (top - bottom) / 3.0
    box = ca.if_else(ca.logic_and(any_seen, box > 1.0), box, nz._DEFAULT_SCALE_PX)
    fresh = state[4] < 0.5
    updated = ca.if_else(fresh, torso, state[3] + nz.SCALE_RATE * (torso - state[3]))
    scale = ca.if_else(measured, updated, ca.if_else(fresh, box, state[3]))
    # A bounding-box guess is not kept: the first real torso measurement replaces it.
    scale_set = ca.logic_or(measured, ca.logic_not(fresh))
    safe = [ca.if_else(centre_set, centre[a], 0.0) for a in (0, 1)]
    rel = []
    for k in range(NUM_KEYPOINTS):
        x = _clip((p[k][0] - safe[0]) / scale) * v[k]
        y = _clip(-((p[k][1] - safe[1]) / scale)) * v[k]
        rel.append((x, y, v[k]))
    direct = [c for r in rel for c in r]
    mirrored = [c for k in _KEYPOINT_MIRROR for c in (-rel[k][0], rel[k][1], rel[k][2])]
    next_state = [
        ca.if_else(centre_set, centre[0], 0.0),
        ca.if_else(centre_set, centre[1], 0.0),
        centre_set,
        ca.if_else(scale_set, scale, 0.0),
        scale_set,
    ]
    return compile_graph(
        "keypoint_stream_features",
        [xy, seen, state],
        [ca.vertcat(*direct, *mirrored), ca.vertcat(*next_state)],
    )


def _clip(x: ca.SX) -> ca.SX:
    return ca.fmin(ca.fmax(x, -nz.CLIP), nz.CLIP)


def _max(xs: list[ca.SX]) -> ca.SX:
    out = xs[0]
    for x in xs[1:]:
        out = ca.fmax(out, x)
    return out


def _min(xs: list[ca.SX]) -> ca.SX:
    out = xs[0]
    for x in xs[1:]:
        out = ca.fmin(out, x)
    return out


@memoized_graph
def answer_function(members: int = 1) -> ca.Function:
    """``head members·2·132 → local 22·4``: each model's 6D rotations of the image and of its
    mirror to quaternions (w ≥ 0); each image's averaged over the models (mean_rotation); the
    mirror's answer mirrored back and averaged with the image's (average_with_mirrored)."""
    head = ca.SX.sym("head", members * 2 * _J * 6)

    def quats(m: int, image: int) -> list[sq.Quat]:
        base = (2 * m + image) * _J * 6
        return [_quat_6d([head[base + 6 * j + i] for i in range(6)]) for j in range(_J)]

    direct, from_mirror = ([quats(m, image) for m in range(members)] for image in (0, 1))
    out: list[ca.SX] = []
    for j in range(_J):
        a = _mean([answers[j] for answers in direct])
        w, x, y, z = _mean([answers[JOINT_MIRROR[j]] for answers in from_mirror])
        out.extend(_mean([a, (w, x, -y, -z)]))  # mirror_rotations: swapped, y and z negated
    return compile_graph(f"keypoint_stream_answer_{members}", [head], [ca.vertcat(*out)])


def _mean(qs: list[sq.Quat]) -> sq.Quat:
    """runtime.agnostic2d.mean_rotation: each turned into the first one's hemisphere, summed,
    normalised (one rotation: itself)."""
    if len(qs) == 1:
        return qs[0]
    first = qs[0]
    total = list(first)
    for q in qs[1:]:
        dot = first[0] * q[0] + first[1] * q[1] + first[2] * q[2] + first[3] * q[3]
        sign = ca.if_else(dot < 0.0, -1.0, 1.0)
        total = [t + sign * c for t, c in zip(total, q, strict=True)]
    return sq.normalize(total)


def _quat_6d(d6: list[ca.SX]) -> sq.Quat:
    """rotation_6d_to_quat for one rotation: Gram–Schmidt, then the quaternion (w ≥ 0) by the
    trace formula where it is well conditioned, else by the largest pivot (Shepperd)."""
    a1, raw2 = d6[:3], d6[3:]
    b1 = sq.scale(1.0 / ca.fmax(sq.norm(a1), 1e-12), a1)
    a2 = sq.sub(raw2, sq.scale(sq.dot(b1, raw2), b1))
    b2 = sq.scale(1.0 / ca.fmax(sq.norm(a2), 1e-12), a2)
    b3 = sq.cross(b1, b2)
    # The matrix has columns b1, b2, b3: m[r][c] = column c's row r.
    m = [[b1[0], b2[0], b3[0]], [b1[1], b2[1], b3[1]], [b1[2], b2[2], b3[2]]]
    trace = m[0][0] + m[1][1] + m[2][2]
    w = 0.5 * ca.sqrt(ca.fmax(1.0 + trace, 1e-12))
    f = 0.25 / w
    fast = sq.normalize(
        (w, (m[2][1] - m[1][2]) * f, (m[0][2] - m[2][0]) * f, (m[1][0] - m[0][1]) * f)
    )
    robust = _shepperd(m)
    well = trace > -0.5
    return tuple(ca.if_else(well, fast[i], robust[i]) for i in range(4))


def _shepperd(m: list[list[ca.SX]]) -> sq.Quat:
    """geometry.quaternion.from_matrix for one matrix: the candidate with the largest pivot,
    normalised, w ≥ 0."""
    cands = [
        (1 + m[0][0] + m[1][1] + m[2][2], m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]),
        (m[2][1] - m[1][2], 1 + m[0][0] - m[1][1] - m[2][2], m[0][1] + m[1][0], m[0][2] + m[2][0]),
        (m[0][2] - m[2][0], m[0][1] + m[1][0], 1 - m[0][0] + m[1][1] - m[2][2], m[1][2] + m[2][1]),
        (m[1][0] - m[0][1], m[0][2] + m[2][0], m[1][2] + m[2][1], 1 - m[0][0] - m[1][1] + m[2][2]),
    ]
    pivots = [cands[0][0], cands[1][1], cands[2][2], cands[3][3]]
    best: tuple[ca.SX, ...] = cands[3]
    best_pivot = pivots[3]
    for i in (2, 1, 0):  # the first of equal pivots wins, as argmax
        take = pivots[i] >= best_pivot
        best = tuple(ca.if_else(take, cands[i][c], best[c]) for c in range(4))
        best_pivot = ca.if_else(take, pivots[i], best_pivot)
    q = sq.normalize(best)
    sign = ca.if_else(q[0] < 0.0, -1.0, 1.0)
    return tuple(sign * c for c in q)
