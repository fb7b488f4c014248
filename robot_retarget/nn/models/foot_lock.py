"""Foot lock: a foot the performer has planted stays planted on the target (torch).

A model that corrects or filters the pose moves the target's feet relative to its root, and
with the root on copy-scaled's path a planted foot then slides: the residual recipe,
cross-validated, slid 0.31 leg lengths/s in the performers' contact frames against
copy-scaled's 0.16; switching its parts off showed the pose path moved the feet, not the root.
Retargeting systems clean this up with leg IK (SAN's code does; GMR and our robot-side base pin
stance feet); this is that step, causal, on the target skeleton, inside the model so training,
``convert`` and ``stream`` agree.

Per frame and leg:

1. **Contact** w ∈ [0, 1] of the performer's ankle: ``robot_retarget.evaluation.foot_contact``'s
   test (slower than 0.3 leg lengths/s horizontally, within 0.1 leg lengths of its lowest point)
   made causal (the lowest point *so far*) and ramped, so a lock fades in and out.
2. **Anchor** A_t = w_t A_t−1 + (1 − w_t) X_t: the target ankle's world position X held while the
   contact lasts (horizontal; the height stays the model's).
3. **Two-bone IK**: the knee bends and the hip turns so the ankle reaches A; the foot keeps its
   world orientation. Where w = 0 the anchor is the ankle itself and the pose is unchanged.

Only leg rotations change; the root path stays the model's, so a lock missed on noisy input
costs a foot's slide in that stance, not a drift of the whole body. Speeds are judged per frame
at the rate the models are trained and evaluated at (30 fps).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from robot_retarget.evaluation.foot_contact import CONTACT_HEIGHT_LEGS, CONTACT_SPEED_LEGS_S
from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import integrate_root, yaw_rotate
from robot_retarget.nn.fk_torch import forward_kinematics
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS
from robot_retarget.skeleton.foot_lock_spec import (
    ANKLES,
    CONTACT_FPS,
    COS_MARGIN,
    HEIGHT_RAMP,
    HINGE_WEIGHT,
    KNEE_AXIS,
    LEGS,
    SPEED_RAMP,
    STRETCH,
)

Tensor = torch.Tensor


def _ramp(x: Tensor, threshold: float, share: float) -> Tensor:
    """1 below threshold·(1 − share), 0 above threshold·(1 + share), linear between."""
    lo, hi = threshold * (1.0 - share), threshold * (1.0 + share)
    return ((hi - x) / (hi - lo)).clamp(0.0, 1.0)


def _turn(v: Tensor, yaw: Tensor) -> Tensor:
    """Vectors (…, K, 3) turned about Y by ``yaw`` (…)."""
    return yaw_rotate(v, yaw[..., None].expand(v.shape[:-1]))


def contact_weights(ankles: Tensor, prev: Tensor, lowest: Tensor, leg: Tensor) -> Tensor:
    """Soft contacts (…, 2) of ankles at world positions ``ankles`` (…, 2, 3) (Y up) that were at
    ``prev`` a frame before and whose lowest height so far is ``lowest`` (…, 2); ``leg`` (…)
    the leg length, same units."""
    step = (ankles - prev)[..., [0, 2]]
    speed = torch.linalg.vector_norm(step, dim=-1) * CONTACT_FPS / leg[..., None]
    above = (ankles[..., 1] - lowest) / leg[..., None]
    return _ramp(speed, CONTACT_SPEED_LEGS_S, SPEED_RAMP) * _ramp(
        above, CONTACT_HEIGHT_LEGS, HEIGHT_RAMP
    )


def held_anchors(points: Tensor, weights: Tensor) -> Tensor:
    """A_t = w_t A_t−1 + (1 − w_t) X_t, A_0 = X_0, for points X (B, T, K, 3) and weights
    (B, T, K), without a loop over time: A_t = Σ_s≤t (1 − w_s) Π_s<r≤t w_r X_s, the products
    as exponentials of differences of cumulative log-weights (a weight of 0 counts as 1e-12)."""
    w = weights.clone()
    w[:, 0] = 0.0
    log_w = torch.cumsum(torch.log(w.clamp_min(1e-12)), dim=1).transpose(1, 2)  # (B, K, T)
    t = points.shape[1]
    lower = torch.ones(t, t, dtype=torch.bool, device=points.device).tril()
    decay = torch.exp((log_w[..., :, None] - log_w[..., None, :]).masked_fill(~lower, -torch.inf))
    mix = decay * (1.0 - w).transpose(1, 2)[..., None, :]  # (B, K, T, T)
    return (mix @ points.transpose(1, 2)).transpose(1, 2)


def _path(root_vel: Tensor) -> tuple[Tensor, Tensor]:
    """Root positions (B, T, 3) and headings (B, T) of velocities (B, T, 4), from the origin
    and heading 0 (the lock's quantities do not depend on where the path starts)."""
    start = root_vel.new_zeros(root_vel.shape[0], 3)
    return integrate_root(root_vel, start, start[:, 0])


def _world_ankles(pos: Tensor, root: Tensor, yaw: Tensor) -> Tensor:
    """The ankles (…, 2, 3) of root-relative joints ``pos`` (…, J, 3) in the heading frame,
    placed at ``root`` (…, 3) turned by ``yaw`` (…)."""
    return root[..., None, :] + _turn(pos[..., ANKLES, :], yaw)


def _lock_to(
    local_quats: Tensor,
    glob: Tensor,
    pos: Tensor,
    anchors: Tensor,
    ankles: Tensor,
    root: Tensor,
    yaw: Tensor,
) -> Tensor:
    """``local_quats`` with the ankles (world, …, 2, 3) moved to the anchors' horizontal place
    at their own height, through :func:`relock` in the root's heading frame."""
    target = torch.cat([anchors[..., :1], ankles[..., 1:2], anchors[..., 2:]], dim=-1)
    return relock(local_quats, glob, pos, _turn(target - root[..., None, :], -yaw))


def _law_of_cosines(l1: Tensor, l2: Tensor, d: Tensor) -> Tensor:
    cos = (l1 * l1 + l2 * l2 - d * d) / (2.0 * l1 * l2)
    return torch.acos(cos.clamp(-1.0 + COS_MARGIN, 1.0 - COS_MARGIN))


def two_bone_ik(
    hip: Tensor, knee: Tensor, ankle: Tensor, target: Tensor, hinge: Tensor
) -> tuple[Tensor, Tensor]:
    """(R_hip, R_knee) (…, 4): turning the shin about the knee by R_knee, then the whole leg
    about the hip by R_hip, puts the ankle at ``target`` (or as near as the leg reaches).
    Points (…, 3); ``hinge`` (…, 3) the knee axis, used where the leg is straight. A target at
    the ankle gives identities, exactly. The knee angles come from the law of cosines with the
    hip–ankle distance kept 1e-4 of the leg's length short of a straight leg (gradients stay
    finite), so a knee within about two degrees of straight is treated as bent that much and
    can land a few millimetres per metre of leg short of the target."""
    thigh, shin = knee - hip, ankle - knee
    l1 = torch.linalg.vector_norm(thigh, dim=-1)
    l2 = torch.linalg.vector_norm(shin, dim=-1)
    lo, hi = (l1 - l2).abs() + STRETCH * (l1 + l2), (l1 + l2) * (1.0 - STRETCH)
    d0 = torch.linalg.vector_norm(ankle - hip, dim=-1).clamp(lo, hi)
    d1 = torch.linalg.vector_norm(target - hip, dim=-1).clamp(lo, hi)
    # Interior knee angle θ: opening the knee by θ1 − θ0 turns the shin away from the thigh.
    bend = _law_of_cosines(l1, l2, d0) - _law_of_cosines(l1, l2, d1)
    axis = torch.linalg.cross(thigh, shin, dim=-1) + HINGE_WEIGHT * (l1 * l2)[..., None] * hinge
    r_knee = qt.from_axis_angle(axis, bend)
    reached = knee + qt.rotate(r_knee, shin)
    return qt.from_two_vectors(reached - hip, target - hip), r_knee


def relock(local_quats: Tensor, glob: Tensor, pos: Tensor, targets: Tensor) -> Tensor:
    """``local_quats`` (…, J, 4) with each leg turned so its ankle reaches ``targets``
    (…, 2, 3); ``glob`` / ``pos`` (…, J, 4) / (…, J, 3) their global rotations and positions
    (root-relative, the targets' frame). The feet keep their global orientation."""
    out = list(local_quats.unbind(dim=-2))
    axis = torch.tensor(KNEE_AXIS, dtype=pos.dtype, device=pos.device)
    for side, (hip, knee, ankle) in enumerate(LEGS):
        g_thigh, g_shin, g_foot = glob[..., hip, :], glob[..., knee, :], glob[..., ankle, :]
        r_hip, r_knee = two_bone_ik(
            pos[..., hip, :],
            pos[..., knee, :],
            pos[..., ankle, :],
            targets[..., side, :],
            qt.rotate(g_shin, axis.expand_as(pos[..., knee, :])),
        )
        new_thigh = qt.mul(r_hip, g_thigh)
        new_shin = qt.mul(r_hip, qt.mul(r_knee, g_shin))
        parent = glob[..., CANONICAL_PARENTS[hip], :]
        out[hip] = qt.mul(qt.conjugate(parent), new_thigh)
        out[knee] = qt.mul(qt.conjugate(new_thigh), new_shin)
        out[ankle] = qt.mul(qt.conjugate(new_shin), g_foot)
    return torch.stack(out, dim=-2)


def _advance(root: Tensor, yaw: Tensor, root_vel: Tensor) -> tuple[Tensor, Tensor]:
    """One frame of :func:`integrate_root`: position (B, 3) and heading (B,) after moving by
    ``root_vel`` (B, 4)."""
    yaw = yaw + root_vel[:, 3]
    return root + yaw_rotate(root_vel[:, :3], yaw), yaw


@dataclass(frozen=True)
class LockState:
    """What a frame-by-frame lock carries to the next frame (batch B)."""

    yaw: Tensor  # (B,) heading turned since the first frame, target path
    root: Tensor  # (B, 3) the target root's world position
    anchors: Tensor  # (B, 2, 3) held ankle positions, world
    src_yaw: Tensor  # (B,) the same for the source's path
    src_root: Tensor  # (B, 3)
    src_ankles: Tensor  # (B, 2, 3) the source's ankles last frame, world
    src_lowest: Tensor  # (B, 2) their lowest height so far


class FootLock(torch.nn.Module):
    """The lock as a stage of a model (module docstring); no parameters."""

    def __init__(self) -> None:
        super().__init__()
        self._state: LockState | None = None

    def forward(
        self,
        local_quats: Tensor,
        root_vel: Tensor,
        offsets: Tensor,
        src_pos: Tensor,
        src_root_vel: Tensor,
        src_leg: Tensor,
    ) -> Tensor:
        """Locked rotations (B, T, J, 4) of a clip: heading-free output rotations, the output's
        root velocities (B, T, 4), the target's offsets (B, J, 3); the source's root-relative
        joints (B, T, J, 3), root velocities (B, T, 4) and leg length (B,)."""
        src_root, src_yaw = _path(src_root_vel)
        src_ankles = _world_ankles(src_pos, src_root, src_yaw)
        prev = torch.cat([src_ankles[:, :1], src_ankles[:, :-1]], dim=1)
        lowest = torch.cummin(src_ankles[..., 1], dim=1).values
        w = contact_weights(src_ankles, prev, lowest, src_leg[:, None])  # (B, T, 2)
        pos, glob = forward_kinematics(CANONICAL_PARENTS, offsets, local_quats)
        root, yaw = _path(root_vel)
        ankles = _world_ankles(pos, root, yaw)
        return _lock_to(local_quats, glob, pos, held_anchors(ankles, w), ankles, root, yaw)

    def reset(self) -> None:
        self._state = None

    def step(
        self,
        local_quats: Tensor,
        root_vel: Tensor,
        offsets: Tensor,
        src_pos: Tensor,
        src_root_vel: Tensor,
        src_leg: Tensor,
    ) -> Tensor:
        """One frame: (B, J, 4), (B, 4), (B, J, 3), (B, J, 3), (B, 4), (B,); equal to
        :meth:`forward`'s frame on the whole clip."""
        s = self._state
        if s is None:  # as integrate_root: the first frame sits at the origin, heading 0
            root = src_root = root_vel.new_zeros(root_vel.shape[0], 3)
            yaw = src_yaw = root_vel.new_zeros(root_vel.shape[0])
        else:
            src_root, src_yaw = _advance(s.src_root, s.src_yaw, src_root_vel)
            root, yaw = _advance(s.root, s.yaw, root_vel)
        src_ankles = _world_ankles(src_pos, src_root, src_yaw)
        prev = src_ankles if s is None else s.src_ankles
        lowest = (
            src_ankles[..., 1] if s is None else torch.minimum(s.src_lowest, src_ankles[..., 1])
        )
        w = contact_weights(src_ankles, prev, lowest, src_leg)[..., None]
        pos, glob = forward_kinematics(CANONICAL_PARENTS, offsets, local_quats)
        ankles = _world_ankles(pos, root, yaw)
        anchor = ankles if s is None else w * s.anchors + (1.0 - w) * ankles
        self._state = LockState(yaw, root, anchor, src_yaw, src_root, src_ankles, lowest)
        return _lock_to(local_quats, glob, pos, anchor, ankles, root, yaw)
