"""Canonical joint positions → local rotations in torch, batched: the twin of the live path's
:class:`robot_retarget.sources.from_positions.PositionsToRotations`.

A position stream (a pose estimator, a marker tracker) reaches the network through that solve:
each joint turned by the smallest rotation that points its bone at the measured child, the Hips
and Spine2 from a triad (primary axis exactly, then the side line), leaves left at the identity.
Training a model on what such a sender delivers needs the same solve on batches of windows with
per-sample skeletons (augmented offsets): that is this module. It runs on whatever device the
positions are on and has no loop over frames (22 joint steps, in order down the tree).
"""

from __future__ import annotations

import torch

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint

Tensor = torch.Tensor

_EPS = 1e-9  # as from_positions
_MIN_SECONDARY_M = 1e-3
_J = len(CANONICAL_PARENTS)
# (joint, primary candidates in order, side pairs in order): as from_positions' _TRIADS,
# _PRIMARY_CHAIN and _TRIAD_FALLBACK.
_TRIADS: dict[int, tuple[tuple[int, ...], tuple[tuple[int, int], ...]]] = {
    Joint.Hips: (
        (Joint.Spine, Joint.Spine1, Joint.Spine2, Joint.Neck),
        ((Joint.LeftUpLeg, Joint.RightUpLeg),),
    ),
    Joint.Spine2: (
        (Joint.Neck, Joint.Head),
        ((Joint.LeftShoulder, Joint.RightShoulder), (Joint.LeftArm, Joint.RightArm)),
    ),
}
_CHILD: dict[int, int] = {}
for _j in range(_J):
    _kids = [c for c, p in enumerate(CANONICAL_PARENTS) if p == _j]
    if len(_kids) == 1:
        _CHILD[_j] = _kids[0]


def _frame(primary: Tensor, secondary: Tensor) -> tuple[Tensor, Tensor]:
    """Orthonormal columns (…, 3, 3) (primary exactly, secondary made orthogonal, their cross)
    and a validity mask (…): False where either axis is (nearly) zero."""
    n1 = torch.linalg.vector_norm(primary, dim=-1, keepdim=True)
    e1 = primary / n1.clamp_min(_EPS)
    s = secondary - e1 * (e1 * secondary).sum(-1, keepdim=True)
    n2 = torch.linalg.vector_norm(s, dim=-1, keepdim=True)
    e2 = s / n2.clamp_min(_EPS)
    e3 = torch.linalg.cross(e1, e2, dim=-1)
    ok = (n1[..., 0] >= _EPS) & (n2[..., 0] >= _EPS)
    return torch.stack([e1, e2, e3], dim=-1), ok


def _shortest_arc(a: Tensor, b: Tensor) -> Tensor:
    """Rotation matrices (…, 3, 3) of the smallest rotations taking unit a onto unit b
    (Rodrigues' form; an opposite pair, where it has no unique answer, gets a half turn)."""
    c = (a * b).sum(-1)
    v = torch.linalg.cross(a, b, dim=-1)
    zero = torch.zeros_like(c)
    k = torch.stack(
        [
            torch.stack([zero, -v[..., 2], v[..., 1]], dim=-1),
            torch.stack([v[..., 2], zero, -v[..., 0]], dim=-1),
            torch.stack([-v[..., 1], v[..., 0], zero], dim=-1),
        ],
        dim=-2,
    )
    eye = torch.eye(3, dtype=a.dtype, device=a.device).expand(k.shape)
    arc = eye + k + (k @ k) / (1.0 + c).clamp_min(1e-9)[..., None, None]
    opposite = c < -1.0 + 1e-9
    if bool(opposite.any()):
        half = qt.to_matrix(qt.from_two_vectors(a, b))
        arc = torch.where(opposite[..., None, None], half, arc)
    return arc


def _pick(points: Tensor, rest: Tensor, joint: int, candidates: tuple[int, ...]) -> Tensor:
    """Per sample, the first candidate whose rest position lies ≥ 1 mm from ``joint``'s (the
    first one when none does): a (…, 3) vector from ``points`` (…, J, 3), ``rest`` (B, J, 3)."""
    chosen = points[..., candidates[0], :] - points[..., joint, :]
    for c in reversed(candidates):
        far = torch.linalg.vector_norm(rest[:, c] - rest[:, joint], dim=-1) >= _MIN_SECONDARY_M
        far = far.view(far.shape[0], *([1] * (points.dim() - 3)), 1)
        chosen = torch.where(far, points[..., c, :] - points[..., joint, :], chosen)
    return chosen


def _side(points: Tensor, rest: Tensor, pairs: tuple[tuple[int, int], ...]) -> Tensor:
    """The first side line (left − right) whose rest length is ≥ 1 mm (the last pair else)."""
    left, right = pairs[-1]
    chosen = points[..., left, :] - points[..., right, :]
    for left, right in reversed(pairs[:-1]):
        far = torch.linalg.vector_norm(rest[:, left] - rest[:, right], dim=-1) >= _MIN_SECONDARY_M
        far = far.view(far.shape[0], *([1] * (points.dim() - 3)), 1)
        chosen = torch.where(far, points[..., left, :] - points[..., right, :], chosen)
    return chosen


def positions_to_rotations(positions: Tensor, offsets: Tensor) -> Tensor:
    """Local rotations (B, T, J, 4) of global joint positions (B, T, J, 3) on skeletons with
    rest ``offsets`` (B, J, 3), as the live path solves them (module docstring)."""
    b = offsets.shape[0]
    rest = torch.zeros_like(offsets)
    for j, p in enumerate(CANONICAL_PARENTS):
        if p >= 0:
            rest[:, j] = rest[:, p] + offsets[:, j]
    rest_t = rest[:, None]  # (B, 1, J, 3): broadcast over frames
    eye = torch.eye(3, dtype=positions.dtype, device=positions.device)
    frames = positions.shape[:-2]
    glob: list[Tensor] = []
    local: list[Tensor] = []
    for j, parent in enumerate(CANONICAL_PARENTS):
        g_parent = eye.expand(*frames, 3, 3) if parent < 0 else glob[parent]
        if j in _TRIADS:
            prims, pairs = _TRIADS[j]
            cur, ok_cur = _frame(_pick(positions, rest, j, prims), _side(positions, rest, pairs))
            ref, ok_ref = _frame(_pick(rest_t, rest, j, prims), _side(rest_t, rest, pairs))
            g = cur @ ref.transpose(-1, -2)
            ok = (ok_cur & ok_ref)[..., None, None]
            g = torch.where(ok, g, g_parent)
            glob.append(g)
            local.append(g_parent.transpose(-1, -2) @ g)
            continue
        child = _CHILD.get(j)
        if child is None:
            loc = eye.expand(*frames, 3, 3)
        else:
            rest_dir = offsets[:, child]
            rest_norm = torch.linalg.vector_norm(rest_dir, dim=-1)
            rest_unit = (rest_dir / rest_norm.clamp_min(_EPS)[:, None]).view(b, 1, 3)
            d = (
                g_parent.transpose(-1, -2)
                @ (positions[..., child, :] - positions[..., j, :])[..., None]
            )[..., 0]
            norm = torch.linalg.vector_norm(d, dim=-1)
            arc = _shortest_arc(rest_unit.expand_as(d), d / norm.clamp_min(_EPS)[..., None])
            ok = ((norm > _EPS) & (rest_norm > _EPS).view(b, 1))[..., None, None]
            loc = torch.where(ok, arc, eye.expand(*frames, 3, 3))
        local.append(loc)
        glob.append(g_parent @ loc)
    return qt.normalize(qt.from_matrix(torch.stack(local, dim=-3)))
