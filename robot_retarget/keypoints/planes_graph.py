"""The image's planes for ``stream`` as compiled SX graphs: one camera frame in three calls
instead of a few hundred numpy calls (robot_retarget.casadi_jit says why).

- :func:`fit_function`: a frame's local rotations and keypoints → its joint positions (root
  at the origin) and the direction cost of every candidate elevation
  (robot_retarget.keypoints.camera_fit.direction_costs for one frame).
- :func:`scale_function`: those positions, the keypoints and one elevation's rotation → the
  frame's image scale (camera_fit.image_scales) and whether three body points were seen.
- :func:`turn_function`: the frame, the camera and the turns applied so far → the turned
  local rotations and the turns now applied (reprojection.plane_changes, the exponential
  average of online_reprojection, reprojection.apply_changes).

Keypoints enter as values with NaN replaced by 0 and a 0/1 mask (SX has no NaN tests). The
numpy code in camera_fit, reprojection and online_reprojection is the reference: the tests
hold the two to 1e-9 on whole streams, missing points and all.
"""

from __future__ import annotations

import casadi as ca

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import compile_graph, memoized_graph
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.keypoints import camera_fit as cf
from robot_retarget.keypoints.coco17 import BODY_JOINTS, LIMB_BONES, NUM_KEYPOINTS, Coco
from robot_retarget.keypoints.reprojection import (
    ALONG_VIEW_SCALE,
    CHANGED,
    DEPTH_BONES,
    DEPTH_SCALE,
    upper_body,
)
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, Joint

Vec = sq.Vec


def _const(v: FloatArray) -> Vec:
    return tuple(ca.SX(float(c)) for c in v)


def _pose(
    local: ca.SX, parents: tuple[int, ...], offsets: FloatArray
) -> tuple[list[sq.Mat], list[Vec]]:
    """Global rotation matrices and root-relative positions of local quaternions (J·4)."""
    glob: list[sq.Mat] = []
    pos: list[Vec] = []
    for j, p in enumerate(parents):
        m = sq.matrix(sq.quat_at(local, j))
        if p < 0:
            glob.append(m)
            pos.append((ca.SX(0.0), ca.SX(0.0), ca.SX(0.0)))
            continue
        glob.append(sq.matmul(glob[p], m))
        pos.append(sq.add(pos[p], sq.rotate(glob[p], _const(offsets[j]))))
    return glob, pos


def _point(xy: ca.SX, k: int) -> tuple[ca.SX, ca.SX]:
    return xy[2 * k], xy[2 * k + 1]


def _project(m: sq.Mat, p: Vec, distance: float) -> tuple[ca.SX, ca.SX]:
    """camera_fit._project of one point through one rotation (row-major 3 × 3)."""
    x, y, z = sq.rotate(m, p)
    s = 1.0 + z / distance
    return x / s, y / s


@memoized_graph
def fit_function(parents: tuple[int, ...], offsets: FloatArray, distance: float) -> ca.Function:
    """``(local J·4, xy 17·2, seen 17) → (positions J·3, costs E)`` (module docstring)."""
    local = ca.SX.sym("local", 4 * len(parents))
    xy = ca.SX.sym("xy", 2 * NUM_KEYPOINTS)
    seen = ca.SX.sym("seen", NUM_KEYPOINTS)
    _glob, pos = _pose(local, parents, offsets)
    segments = []
    for (j0, j1), (k0, k1) in zip(cf.FIT_SEGMENTS, cf.FIT_KEYPOINTS, strict=True):
        (x0, y0), (x1, y1) = _point(xy, k0), _point(xy, k1)
        both = seen[k0] * seen[k1]
        sx, sy = both * (x1 - x0), both * (y1 - y0)
        weight = ca.sqrt(sx * sx + sy * sy)  # 0 where either end is missing
        inv = 1.0 / ca.fmax(weight, 1e-9)
        segments.append((j0, j1, sx * inv, sy * inv, weight))
    costs = []
    for rotation in cf.candidate_rotations():
        m = _const(rotation.reshape(-1))
        proj = {j: _project(m, pos[j], distance) for s in segments for j in s[:2]}
        total = ca.SX(0.0)
        for j0, j1, dx, dy, weight in segments:
            vx, vy = proj[j1][0] - proj[j0][0], proj[j1][1] - proj[j0][1]
            cos = (vx * dx + vy * dy) / ca.fmax(ca.sqrt(vx * vx + vy * vy), 1e-12)
            total = total + weight * (1.0 - cos)
        costs.append(total)
    flat = [c for p in pos for c in p]
    return compile_graph(
        "keypoint_planes_fit", [local, xy, seen], [ca.vertcat(*flat), ca.vertcat(*costs)]
    )


@memoized_graph
def scale_function(distance: float) -> ca.Function:
    """``(positions J·3, xy 17·2, seen 17, rotation 9) → (scale, enough)``: camera_fit's image
    scale of one frame; ``enough`` 1 where three or more body points were seen (else the
    scale means nothing)."""
    pos = ca.SX.sym("positions", 3 * len(CANONICAL_JOINTS))
    xy = ca.SX.sym("xy", 2 * NUM_KEYPOINTS)
    seen = ca.SX.sym("seen", NUM_KEYPOINTS)
    rot = ca.SX.sym("rotation", 9)
    m = tuple(rot[i] for i in range(9))
    proj, obs, w = [], [], []
    for k, j in BODY_JOINTS.items():
        proj.append(_project(m, sq.vec_at(pos, j), distance))
        obs.append(_point(xy, k))
        w.append(seen[k])
    count = sum(w[1:], w[0])
    n = ca.fmax(count, 1.0)
    mean = [
        sum((w[i] * c[a] for i, c in enumerate(cs)), ca.SX(0.0)) / n
        for cs in (proj, obs)
        for a in (0, 1)
    ]
    num, den = ca.SX(0.0), ca.SX(0.0)
    for i in range(len(w)):
        px, py = proj[i][0] - mean[0], proj[i][1] - mean[1]
        ox, oy = obs[i][0] - mean[2], obs[i][1] - mean[3]
        num = num + w[i] * (px * ox + py * oy)
        den = den + w[i] * (px * px + py * py)
    return compile_graph(
        "keypoint_planes_scale", [pos, xy, seen, rot], [num / ca.fmax(den, 1e-12), count >= 3.0]
    )


def _ray(xy: ca.SX, k: int | tuple[int, int], camera: tuple[ca.SX, ca.SX, ca.SX]) -> Vec:
    """camera_fit.CameraEstimate.rays of keypoint ``k`` (or the midpoint of a pair)."""
    cx, cy, focal = camera
    if isinstance(k, tuple):
        (xa, ya), (xb, yb) = _point(xy, k[0]), _point(xy, k[1])
        x, y = 0.5 * (xa + xb), 0.5 * (ya + yb)
    else:
        x, y = _point(xy, k)
    return (x - cx, y - cy, focal)


def _into_plane(d: Vec, ray_a: Vec, ray_b: Vec, seen: ca.SX, weighted: bool) -> Vec:
    """reprojection._into_planes of one unit direction (camera frame); ``seen`` 0 → as it is."""
    normal = sq.cross(ray_a, ray_b)
    size = sq.norm(normal)
    ok = ca.logic_and(seen > 0.5, size > 1e-9)
    n = tuple(ca.if_else(ok, c / ca.fmax(size, 1e-9), 0.0) for c in normal)
    inside = sq.reject(d, n)
    if weighted:
        m2 = d[0] * d[0] + d[1] * d[1]
        share = m2 / (m2 + ALONG_VIEW_SCALE**2)
        inside = tuple(a + share * (b - a) for a, b in zip(d, inside, strict=True))
    length = sq.norm(inside)
    ok = ca.logic_and(ok, length > 1e-9)
    turned = tuple(
        ca.if_else(ok, c / ca.fmax(length, 1e-9), a) for a, c in zip(d, inside, strict=True)
    )
    return _image_side(turned, d, ray_a, ray_b, ok)


def _image_side(turned: Vec, before: Vec, ray_a: Vec, ray_b: Vec, ok: ca.SX) -> Vec:
    """reprojection._image_side of one unit direction: mirrored along the view onto the side
    its keypoints put it, unless that turns it 90° or more from ``before``."""
    across = sq.sub(sq.unit_or_zero(ray_b), sq.unit_or_zero(ray_a))
    size = sq.norm(across)
    ok = ca.logic_and(ok, size > 1e-12)
    across = sq.scale(1.0 / ca.fmax(size, 1e-12), across)
    side = sq.dot(turned, across)
    mirrored = sq.sub(turned, sq.scale(2.0 * side, across))
    flip = ca.logic_and(ca.logic_and(ok, side < 0.0), sq.dot(mirrored, before) > 0.0)
    return tuple(ca.if_else(flip, m, t) for m, t in zip(mirrored, turned, strict=True))


def _depth_from_length(d: Vec, ray_a: Vec, ray_b: Vec, expected: ca.SX, seen: ca.SX) -> Vec:
    """reprojection.depth_from_length of one unit direction (camera frame); ``seen`` 0 or
    ``expected`` ≤ 0 → as it is."""
    view = sq.add(ray_a, ray_b)
    view = sq.scale(1.0 / ca.fmax(sq.norm(view), 1e-9), view)  # a missing point's rays are 0
    image_len = ca.sqrt((ray_b[0] - ray_a[0]) ** 2 + (ray_b[1] - ray_a[1]) ** 2)
    sin_m = ca.fmin(ca.fmax(sq.dot(d, view), -1.0), 1.0)
    across = sq.sub(d, sq.scale(sin_m, view))
    across_len = sq.norm(across)
    ok = ca.logic_and(ca.logic_and(seen > 0.5, expected > 0.0), across_len > 1e-9)
    across = sq.scale(1.0 / ca.fmax(across_len, 1e-9), across)
    cos_i = ca.fmin(ca.fmax(image_len / ca.fmax(expected, 1e-12), 0.0), 1.0)
    sin_i2 = 1.0 - cos_i * cos_i
    share = sin_i2 / (sin_i2 + DEPTH_SCALE**2)
    phi_m = ca.asin(sin_m)
    phi_i = ca.if_else(sin_m < 0.0, -1.0, 1.0) * ca.acos(cos_i)
    phi = phi_m + share * (phi_i - phi_m)
    moved = sq.add(sq.scale(ca.cos(phi), across), sq.scale(ca.sin(phi), view))
    return tuple(ca.if_else(ok, m, a) for m, a in zip(moved, d, strict=True))


def _turn(a: Vec, b: Vec) -> sq.Mat:
    """reprojection._turns: the shortest-arc rotation matrix taking unit ``a`` onto ``b``."""
    vx, vy, vz = sq.cross(a, b)
    c = sq.dot(a, b)
    k = 1.0 / ca.fmax(1.0 + c, 1e-12)
    return (
        c + k * vx * vx, -vz + k * vx * vy, vy + k * vx * vz,
        vz + k * vy * vx, c + k * vy * vy, -vx + k * vy * vz,
        -vy + k * vz * vx, vx + k * vz * vy, c + k * vz * vz,
    )  # fmt: skip


def _from_matrix(m: sq.Mat) -> sq.Quat:
    """reprojection.plane_changes' quaternion of a turn (w > 0): from the trace, or Shepperd's
    largest pivot past ~160° (quaternion.from_matrix)."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    trace = m00 + m11 + m22
    w = 0.5 * ca.sqrt(ca.fmax(1.0 + trace, 1e-12))
    direct = (w, (m21 - m12) / (4.0 * w), (m02 - m20) / (4.0 * w), (m10 - m01) / (4.0 * w))
    cands = [  # (pivot, quaternion w-first), as quaternion.from_matrix
        (1 + m00 + m11 + m22, (1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01)),
        (1 + m00 - m11 - m22, (m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20)),
        (1 - m00 + m11 - m22, (m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21)),
        (1 - m00 - m11 + m22, (m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22)),
    ]
    best_pivot, first = cands[0]
    best: sq.Quat = first
    for pivot, q in cands[1:]:
        better = pivot > best_pivot
        best = tuple(ca.if_else(better, a, b) for a, b in zip(q, best, strict=True))
        best_pivot = ca.if_else(better, pivot, best_pivot)
    shep = sq.normalize(best)
    sign = ca.if_else(shep[0] < 0.0, -1.0, 1.0)
    robust = tuple(sign * c for c in shep)
    return tuple(ca.if_else(trace < -0.9, r, d) for r, d in zip(robust, direct, strict=True))


@memoized_graph
def turn_function(parents: tuple[int, ...], offsets: FloatArray, distance: float) -> ca.Function:
    """``(local J·4, xy 17·2, seen 17, rotation 9, camera (cx, cy, focal), applied C·4, rate,
    image scale) → (turned local J·4, applied C·4)``: the frame's bones turned toward the
    image's planes (reprojection.plane_changes, with the depth cue where the image scale is
    positive), the turns averaged into those applied so far, and applied
    (reprojection.apply_changes); C = len(CHANGED)."""
    local = ca.SX.sym("local", 4 * len(parents))
    xy = ca.SX.sym("xy", 2 * NUM_KEYPOINTS)
    seen = ca.SX.sym("seen", NUM_KEYPOINTS)
    rot = ca.SX.sym("rotation", 9)
    cam = ca.SX.sym("camera", 3)
    applied = ca.SX.sym("applied", 4 * len(CHANGED))
    rate = ca.SX.sym("rate")
    image_scale = ca.SX.sym("image_scale")
    camera = (cam[0], cam[1], cam[2])
    r = tuple(rot[i] for i in range(9))
    rt = sq.transpose(r)
    glob0, pos = _pose(local, parents, offsets)

    # The torso, hip centre → shoulder centre, about the spine with everything above it.
    lh, rh, ls, rs = Coco.left_hip, Coco.right_hip, Coco.left_shoulder, Coco.right_shoulder
    hip3 = tuple(
        0.5 * (a + b) for a, b in zip(pos[Joint.LeftUpLeg], pos[Joint.RightUpLeg], strict=True)
    )
    sho3 = tuple(
        0.5 * (a + b) for a, b in zip(pos[Joint.LeftArm], pos[Joint.RightArm], strict=True)
    )
    d, _ = sq.unit(sq.sub(sho3, hip3))
    before = sq.rotate(r, d)
    both = seen[lh] * seen[rh] * seen[ls] * seen[rs]
    after = _into_plane(before, _ray(xy, (lh, rh), camera), _ray(xy, (ls, rs), camera), both, False)
    torso = _turn(sq.rotate(rt, before), sq.rotate(rt, after))
    upper = set(upper_body(parents))
    glob = [sq.matmul(torso, g) if j in upper else g for j, g in enumerate(glob0)]

    # Each limb bone on its own (its child keeps its global rotation).
    turned = list(glob)
    for (joint, child, k0, k1), cued in zip(LIMB_BONES, DEPTH_BONES, strict=True):
        bone, _ = sq.unit(sq.rotate(glob[joint], _const(offsets[child])))
        before = sq.rotate(r, bone)
        ok = seen[k0] * seen[k1]
        ray_a, ray_b = _ray(xy, int(k0), camera), _ray(xy, int(k1), camera)
        after = _into_plane(before, ray_a, ray_b, ok, True)
        if cued:  # its full image length: the image scale × its length, at its midpoint's depth
            depth_off = sq.rotate(r, sq.scale(ca.SX(0.5), sq.add(pos[joint], pos[child])))[2]
            length = float(sum(c * c for c in offsets[child]) ** 0.5)
            expected = image_scale * length / (1.0 + depth_off / distance)
            after = _depth_from_length(after, ray_a, ray_b, expected, ok)
        turned[joint] = sq.matmul(_turn(sq.rotate(rt, before), sq.rotate(rt, after)), glob[joint])

    # The changed joints' local turns, averaged into those applied so far, then applied.
    out = [sq.quat_at(local, j) for j in range(len(parents))]
    now = []
    for i, j in enumerate(CHANGED):
        p = parents[j]
        before_m = sq.matmul(sq.transpose(glob0[p]), glob0[j])
        after_m = sq.matmul(sq.transpose(turned[p]), turned[j])
        change = _from_matrix(sq.matmul(after_m, sq.transpose(before_m)))
        old = sq.quat_at(applied, i)
        mixed = sq.normalize(tuple(a + rate * (b - a) for a, b in zip(old, change, strict=True)))
        now.append(mixed)
        out[j] = sq.normalize(sq.qmul(mixed, out[j]))
    return compile_graph(
        "keypoint_planes_turn",
        [local, xy, seen, rot, cam, applied, rate, image_scale],
        [ca.vertcat(*(c for q in out for c in q)), ca.vertcat(*(c for q in now for c in q))],
    )
