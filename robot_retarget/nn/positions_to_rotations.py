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
from robot_retarget.skeleton import position_solve_spec as spec
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS

Tensor = torch.Tensor

# Per triad joint, as lines (a, b) from point b to point a: the primary axis's candidates
# (the first is the default), then the side line's (the last is the default).
_TRIADS: dict[int, tuple[tuple[tuple[int, int], ...], tuple[tuple[int, int], ...]]] = {
    j: (
        tuple((c, j) for c in spec.PRIMARY_CHAIN[j]),
        (side, *((spec.TRIAD_FALLBACK[j],) if j in spec.TRIAD_FALLBACK else ())),
    )
    for j, (_primary, side) in spec.TRIADS.items()
}
_CHILD = spec.single_children(CANONICAL_PARENTS)


def _frame(primary: Tensor, secondary: Tensor) -> tuple[Tensor, Tensor]:
    """Orthonormal columns (…, 3, 3) (primary exactly, secondary made orthogonal, their cross)
    and a validity mask (…): False where either axis is (nearly) zero."""
    n1 = torch.linalg.vector_norm(primary, dim=-1, keepdim=True)
    e1 = primary / n1.clamp_min(spec.EPS)
    s = secondary - e1 * (e1 * secondary).sum(-1, keepdim=True)
    n2 = torch.linalg.vector_norm(s, dim=-1, keepdim=True)
    e2 = s / n2.clamp_min(spec.EPS)
    e3 = torch.linalg.cross(e1, e2, dim=-1)
    ok = (n1[..., 0] >= spec.EPS) & (n2[..., 0] >= spec.EPS)
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


def _first_long(
    points: Tensor, rest: Tensor, lines: tuple[tuple[int, int], ...], fallback: int
) -> Tensor:
    """Per sample, ``points[a] − points[b]`` (…, 3) for the first line (a, b) of ``lines`` whose
    rest length is ≥ 1 mm, and for the line ``fallback`` where none is; ``points`` (…, J, 3),
    ``rest`` (B, J, 3)."""
    a, b = lines[fallback]
    chosen = points[..., a, :] - points[..., b, :]
    for a, b in reversed(lines):
        far = torch.linalg.vector_norm(rest[:, a] - rest[:, b], dim=-1) >= spec.MIN_SECONDARY_M
        far = far.view(far.shape[0], *([1] * (points.dim() - 3)), 1)
        chosen = torch.where(far, points[..., a, :] - points[..., b, :], chosen)
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
            prims, sides = _TRIADS[j]
            cur, ok_cur = _frame(
                _first_long(positions, rest, prims, 0), _first_long(positions, rest, sides, -1)
            )
            ref, ok_ref = _frame(
                _first_long(rest_t, rest, prims, 0), _first_long(rest_t, rest, sides, -1)
            )
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
            rest_unit = (rest_dir / rest_norm.clamp_min(spec.EPS)[:, None]).view(b, 1, 3)
            d = (
                g_parent.transpose(-1, -2)
                @ (positions[..., child, :] - positions[..., j, :])[..., None]
            )[..., 0]
            norm = torch.linalg.vector_norm(d, dim=-1)
            arc = _shortest_arc(rest_unit.expand_as(d), d / norm.clamp_min(spec.EPS)[..., None])
            ok = ((norm > spec.EPS) & (rest_norm > spec.EPS).view(b, 1))[..., None, None]
            loc = torch.where(ok, arc, eye.expand(*frames, 3, 3))
        local.append(loc)
        glob.append(g_parent @ loc)
    return qt.normalize(qt.from_matrix(torch.stack(local, dim=-3)))
