"""The foot lock's frame step as one SX graph (the twin of
:meth:`robot_retarget.nn.models.foot_lock.FootLock.step`), compiled as part of the residual
model's output stage (:func:`robot_retarget.runtime.residual_graphs.output_lock_graph`).

``foot_lock(q_src, root_src, offsets_src, q_out, root_out, offsets_tgt, leg, rate, state,
first) → (legs, state_next)``:

- ``q_src`` / ``root_src``: the performer's frame as it arrived (rotations with heading, root
  position), whose ankles' world positions give the contact test;
- ``q_out`` / ``root_out``: the model's output frame (heading on the root) and its integrated
  root position, whose ankles are held;
- ``leg``: the performer's leg length; ``rate``: the frame rate the step runs at (Hz), which
  turns a frame's displacement into a speed for the contact test;
- ``state``: per leg the held anchor (3), the performer's ankle last frame (3) and its lowest
  height so far (1), left then right: 14 numbers; ``first`` is 1 on a sequence's first frame,
  which starts the state from this frame;
- ``legs``: the new local rotations of hip, knee and ankle, left then right (24 numbers).

The torch step works in frames integrated from the first frame's heading; this graph works in
the input's world frame. Every quantity involved (horizontal speeds, heights above the lowest
point, a point held in place, the IK) is unchanged by a turn about the vertical and a shift, so
the two agree to rounding (tested).
"""

from __future__ import annotations

import casadi as ca

from robot_retarget.evaluation.foot_contact import CONTACT_HEIGHT_LEGS, CONTACT_SPEED_LEGS_S
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.skeleton import foot_lock_spec as spec
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS

STATE_SIZE = 14
LEG_JOINTS = tuple(j for leg in spec.LEGS for j in leg)


def _ramp(x: ca.SX, threshold: float, share: float) -> ca.SX:
    lo, hi = threshold * (1.0 - share), threshold * (1.0 + share)
    return ca.fmin(ca.fmax((hi - x) / (hi - lo), 0.0), 1.0)


def _leg_chain(
    q: ca.SX, offsets: ca.SX, root: sq.Vec, leg: tuple[int, int, int]
) -> tuple[list[sq.Vec], list[sq.Quat], sq.Quat]:
    """World positions and global rotations of a leg's hip, knee and ankle, and the hip's
    parent's global rotation (the root's)."""
    g_root = sq.quat_at(q, 0)
    parent = CANONICAL_PARENTS[leg[0]]
    assert parent == 0, "the legs hang from the root"
    pos: list[sq.Vec] = []
    glob: list[sq.Quat] = []
    p, g = root, g_root
    for joint in leg:
        p = sq.add(p, sq.qrotate(g, sq.vec_at(offsets, joint)))
        g = sq.qmul(g, sq.quat_at(q, joint))
        pos.append(p)
        glob.append(g)
    return pos, glob, g_root


def _law_of_cosines(l1: ca.SX, l2: ca.SX, d: ca.SX) -> ca.SX:
    cos = (l1 * l1 + l2 * l2 - d * d) / (2.0 * l1 * l2)
    margin = spec.COS_MARGIN
    return ca.acos(ca.fmin(ca.fmax(cos, -1.0 + margin), 1.0 - margin))


def _from_axis_angle(axis: sq.Vec, angle: ca.SX) -> sq.Quat:
    u = sq.unit_or_zero(axis)
    s = ca.sin(0.5 * angle)
    return (ca.cos(0.5 * angle), s * u[0], s * u[1], s * u[2])


def _from_two_vectors(a: sq.Vec, b: sq.Vec) -> sq.Quat:
    """As ``quaternion_torch.from_two_vectors`` (same degenerate cases)."""
    ua = sq.unit_or_zero(a)
    ub = sq.unit_or_zero(b)
    d = sq.dot(ua, ub)
    c = sq.cross(ua, ub)
    s2 = sq.dot(c, c)
    degenerate = ca.logic_or(s2 <= 1e-300, ca.logic_and(s2 < 1e-16, d < 0.0))
    s = ca.sqrt(ca.if_else(degenerate, 1.0, s2))
    half = 0.5 * ca.atan2(ca.if_else(degenerate, 0.0, s), d)
    helper = ca.if_else(ca.fabs(ua[0]) < 0.9, 1.0, 0.0)
    perp = sq.unit_or_zero(sq.cross(ua, (helper, 1.0 - helper, ca.SX(0.0))))
    axis = tuple(ca.if_else(degenerate, perp[i], c[i] / s) for i in range(3))
    sh = ca.sin(half)
    return (ca.cos(half), sh * axis[0], sh * axis[1], sh * axis[2])


def _two_bone_ik(
    hip: sq.Vec, knee: sq.Vec, ankle: sq.Vec, target: sq.Vec, hinge: sq.Vec
) -> tuple[sq.Quat, sq.Quat]:
    thigh, shin = sq.sub(knee, hip), sq.sub(ankle, knee)
    l1, l2 = sq.norm(thigh), sq.norm(shin)
    stretch = spec.STRETCH
    lo, hi = ca.fabs(l1 - l2) + stretch * (l1 + l2), (l1 + l2) * (1.0 - stretch)
    d0 = ca.fmin(ca.fmax(sq.norm(sq.sub(ankle, hip)), lo), hi)
    d1 = ca.fmin(ca.fmax(sq.norm(sq.sub(target, hip)), lo), hi)
    bend = _law_of_cosines(l1, l2, d0) - _law_of_cosines(l1, l2, d1)
    axis = sq.add(sq.cross(thigh, shin), sq.scale(spec.HINGE_WEIGHT * l1 * l2, hinge))
    r_knee = _from_axis_angle(axis, bend)
    reached = sq.add(knee, sq.qrotate(r_knee, shin))
    return _from_two_vectors(sq.sub(reached, hip), sq.sub(target, hip)), r_knee


def foot_lock_graph() -> tuple[list[ca.SX], list[ca.SX]]:
    j = len(CANONICAL_PARENTS)
    q_src = ca.SX.sym("q_src", 4 * j)
    root_src = ca.SX.sym("root_src", 3)
    off_src = ca.SX.sym("offsets_src", 3 * j)
    q_out = ca.SX.sym("q_out", 4 * j)
    root_out = ca.SX.sym("root_out", 3)
    off_tgt = ca.SX.sym("offsets_tgt", 3 * j)
    leg_len = ca.SX.sym("leg")
    rate = ca.SX.sym("rate")
    state = ca.SX.sym("state", STATE_SIZE)
    first = ca.SX.sym("first")
    legs: list[ca.SX] = []
    state_next: list[ca.SX] = []
    src_root = sq.vec_at(root_src, 0)
    out_root = sq.vec_at(root_out, 0)
    for side, leg in enumerate(spec.LEGS):
        base = 7 * side
        anchor_prev = tuple(state[base + i] for i in range(3))
        ankle_prev = tuple(state[base + 3 + i] for i in range(3))
        lowest_prev = state[base + 6]
        src_pos, _, _ = _leg_chain(q_src, off_src, src_root, leg)
        src_ankle = src_pos[2]
        ankle_before = tuple(ca.if_else(first, src_ankle[i], ankle_prev[i]) for i in range(3))
        lowest = ca.if_else(first, src_ankle[1], ca.fmin(lowest_prev, src_ankle[1]))
        dx, dz = src_ankle[0] - ankle_before[0], src_ankle[2] - ankle_before[2]
        speed = ca.sqrt(dx * dx + dz * dz) * rate / leg_len
        above = (src_ankle[1] - lowest) / leg_len
        w = _ramp(speed, CONTACT_SPEED_LEGS_S, spec.SPEED_RAMP) * _ramp(
            above, CONTACT_HEIGHT_LEGS, spec.HEIGHT_RAMP
        )
        pos, glob, g_root = _leg_chain(q_out, off_tgt, out_root, leg)
        ankle = pos[2]
        anchor = tuple(
            ca.if_else(first, ankle[i], w * anchor_prev[i] + (1.0 - w) * ankle[i]) for i in range(3)
        )
        target = (anchor[0], ankle[1], anchor[2])
        hinge = sq.qrotate(glob[1], tuple(ca.SX(c) for c in spec.KNEE_AXIS))
        r_hip, r_knee = _two_bone_ik(pos[0], pos[1], ankle, target, hinge)
        new_thigh = sq.qmul(r_hip, glob[0])
        new_shin = sq.qmul(r_hip, sq.qmul(r_knee, glob[1]))
        legs.extend(sq.qmul(sq.conj(g_root), new_thigh))
        legs.extend(sq.qmul(sq.conj(new_thigh), new_shin))
        legs.extend(sq.qmul(sq.conj(new_shin), glob[2]))
        state_next.extend((*anchor, *src_ankle, lowest))
    inputs = [q_src, root_src, off_src, q_out, root_out, off_tgt, leg_len, rate, state, first]
    return inputs, [ca.vertcat(*legs), ca.vertcat(*state_next)]
