"""The seed papers' motion features in torch, and their inverse (root integration).

NKN and PMnet (after Holden et al. 2016) split a motion into

- a *local pose*: every joint's position relative to the root, with the heading (rotation
  about the up axis Y) removed, (B, T, J, 3) metres, and
- a *root movement*: per frame, the root's displacement since the previous frame expressed in
  the current heading frame (x, y, z, metres per frame) and the heading change (yaw rate,
  radians per frame), (B, T, 4).

The heading is the yaw of the hips' left-right axis: in the canonical rest pose (facing +Z,
left = +X) that axis is the root frame's +X, so ``yaw = atan2(-l_z, l_x)`` with ``l`` the root
rotation applied to +X; yaw 0 means facing +Z. A pure yaw rotation about Y by ψ gives yaw ψ.

Differences are *backward* (frame t against t − 1, frame 0 is zero), so the features of frame t
depend only on frames ≤ t: the clip path and the online path (:class:`FeatureStream`) compute
the same numbers, and integration inverts them exactly given the first frame's root position
and heading.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import torch

from robot_retarget.geometry.quaternion_tables import matrix_table
from robot_retarget.nn import fk_torch
from robot_retarget.runtime.pmnet import PMNET_SCALE_JOINTS
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS
from robot_retarget.skeleton.tree_tables import ancestor_matrix, pointer_jumps

Tensor = torch.Tensor

ROOT_VEL_DIM = 4
"""Root movement features per frame: dx, dy, dz (heading frame, m/frame), dyaw (rad/frame)."""


# Constants and caches are built outside inference mode even when first needed inside it:
# an inference-mode tensor saved for backward later breaks training in the same process.
with torch.inference_mode(False):
    _YAW_MUL_SIGNS = torch.tensor([-1.0, 1.0, 1.0, -1.0])
    _YAW_MUL_PERM = torch.tensor([2, 3, 0, 1])
    _PMNET_SCALE_INDEX = torch.tensor(PMNET_SCALE_JOINTS)


def wrap_angle(angle_rad: Tensor) -> Tensor:
    """Wrap angles to (−π, π]."""
    return math.pi - torch.remainder(math.pi - angle_rad, 2.0 * math.pi)


def yaw_quat(yaw_rad: Tensor) -> Tensor:
    """Quaternions (…, 4) of rotations by ``yaw_rad`` (…) about the up axis Y."""
    half = 0.5 * yaw_rad
    zero = torch.zeros_like(half)
    return torch.stack([torch.cos(half), zero, torch.sin(half), zero], dim=-1)


def heading_yaw(root_quats: Tensor) -> Tensor:
    """Heading (rad, (−π, π]) of root orientations (…, 4): yaw of the hips' left-right axis."""
    w, x, y, z = root_quats.unbind(-1)
    # Root rotation applied to +X (first column of its matrix); only l_x and l_z matter.
    left_x = 1.0 - 2.0 * (y * y + z * z)
    left_z = 2.0 * (x * z - w * y)
    return torch.atan2(-left_z, left_x)


def yaw_mul(yaw_rad: Tensor, q: Tensor) -> Tensor:
    """yaw_quat(yaw_rad) ⊗ q for quaternions q (…, 4), written out (a third of the ops)."""
    half = 0.5 * yaw_rad[..., None]
    # (c, 0, s, 0) ⊗ (w, x, y, z) = c·(w, x, y, z) + s·(−y, z, w, −x)
    swapped = q.index_select(-1, _YAW_MUL_PERM.to(q.device)) * _YAW_MUL_SIGNS.to(q)
    return torch.cos(half) * q + torch.sin(half) * swapped


def yaw_rotate(v: Tensor, yaw_rad: Tensor) -> Tensor:
    """Rotate vectors v (…, 3) about the up axis Y by ``yaw_rad`` (…)."""
    c = torch.cos(yaw_rad)[..., None]
    s = torch.sin(yaw_rad)[..., None]
    x, y, z = v[..., 0:1], v[..., 1:2], v[..., 2:3]
    return torch.cat([c * x + s * z, y, c * z - s * x], dim=-1)


def remove_heading(local_quats: Tensor, yaw_rad: Tensor) -> Tensor:
    """Local rotations (…, J, 4) whose root entry has the heading ``yaw_rad`` (…) removed."""
    root = yaw_mul(-yaw_rad, local_quats[..., 0, :])
    return torch.cat([root[..., None, :], local_quats[..., 1:, :]], dim=-2)


def apply_heading(local_quats: Tensor, yaw_rad: Tensor) -> Tensor:
    """Inverse of :func:`remove_heading`: put the heading ``yaw_rad`` (…) back on the root."""
    return remove_heading(local_quats, -yaw_rad)


def local_positions(
    heading_free_quats: Tensor,
    offsets: Tensor,
    parents: Sequence[int] = CANONICAL_PARENTS,
) -> Tensor:
    """Joint positions (B, T, J, 3) relative to the root, heading removed: the FK layer.

    ``offsets`` (B, J, 3) is each sample's rest skeleton, broadcast over time.
    """
    positions, _ = fk_torch.forward_kinematics(parents, offsets, heading_free_quats)
    return positions


@dataclass(frozen=True)
class MotionFeatures:
    """A motion in the papers' representation (see the module docstring).

    ``local_quats`` are the rotations with the heading removed from the root entry; ``yaw`` the
    removed heading per frame. ``local_pos`` is FK of ``local_quats`` on the motion's skeleton.
    """

    local_pos: Tensor  # (B, T, J, 3) m, root-relative, heading frame
    root_vel: Tensor  # (B, T, 4): dx, dy, dz m/frame (heading frame), dyaw rad/frame
    local_quats: Tensor  # (B, T, J, 4)
    yaw: Tensor  # (B, T) rad

    @property
    def pose_flat(self) -> Tensor:
        """Local pose as (B, T, 3J): the papers' p_t."""
        return self.local_pos.flatten(-2)

    @property
    def x(self) -> Tensor:
        """NKN's x_t = [p_t, v_t], (B, T, 3J + 4)."""
        return torch.cat([self.pose_flat, self.root_vel], dim=-1)


def root_velocity(root_pos: Tensor, yaw_rad: Tensor) -> Tensor:
    """Backward root velocities (B, T, 4) from positions (B, T, 3) and headings (B, T)."""
    disp = torch.cat([torch.zeros_like(root_pos[:, :1]), root_pos[:, 1:] - root_pos[:, :-1]], 1)
    dyaw = torch.cat(
        [torch.zeros_like(yaw_rad[:, :1]), wrap_angle(yaw_rad[:, 1:] - yaw_rad[:, :-1])], 1
    )
    disp_local = yaw_rotate(disp, -yaw_rad)
    return torch.cat([disp_local, dyaw[..., None]], dim=-1)


def compute_features(
    local_quats: Tensor,
    root_pos: Tensor,
    offsets: Tensor,
    parents: Sequence[int] = CANONICAL_PARENTS,
) -> MotionFeatures:
    """Features of a batch of motions.

    ``local_quats`` (B, T, J, 4) unit, root entry = global root orientation; ``root_pos``
    (B, T, 3) metres; ``offsets`` (B, J, 3) rest offsets of each sample's skeleton.
    """
    _check_motion(local_quats, root_pos, offsets)
    yaw = heading_yaw(local_quats[..., 0, :])
    free = remove_heading(local_quats, yaw)
    pos = local_positions(free, offsets, parents)
    return MotionFeatures(
        local_pos=pos, root_vel=root_velocity(root_pos, yaw), local_quats=free, yaw=yaw
    )


def integrate_root(
    root_vel: Tensor, init_root_pos: Tensor, init_yaw: Tensor
) -> tuple[Tensor, Tensor]:
    """Root positions (B, T, 3) and headings (B, T) from velocities (B, T, 4).

    Frame 0 sits at ``init_root_pos`` (B, 3) with heading ``init_yaw`` (B,); frame 0's velocity
    is ignored (it is zero by construction). Exact inverse of :func:`root_velocity`.
    """
    zero = torch.zeros_like(root_vel[:, :1])
    vel = torch.cat([zero, root_vel[:, 1:]], dim=1)
    yaw = init_yaw[:, None] + torch.cumsum(vel[..., 3], dim=1)
    disp = yaw_rotate(vel[..., :3], yaw)
    pos = init_root_pos[:, None, :] + torch.cumsum(disp, dim=1)
    return pos, yaw


def skeleton_height(offsets: Tensor, parents: Sequence[int] = CANONICAL_PARENTS) -> Tensor:
    """Vertical extent (B,) of the rest pose, metres: the height ratio of copy-scaled."""
    rest = _rest_positions(offsets, parents)
    return rest[..., 1].amax(dim=-1) - rest[..., 1].amin(dim=-1)


def pmnet_scale(offsets: Tensor) -> Tensor:
    """PMnet's scale factor S (B,) (eq. 6, N_s = 1): root, spine, neck and left-leg bones."""
    lengths = torch.linalg.vector_norm(
        offsets.index_select(1, _PMNET_SCALE_INDEX.to(offsets.device)), dim=-1
    )
    return lengths.sum(dim=-1)


def _rest_positions(offsets: Tensor, parents: Sequence[int]) -> Tensor:
    return _ancestor_matrix(tuple(parents)).to(offsets) @ offsets


@lru_cache(maxsize=16)
@torch.inference_mode(False)
def _ancestor_matrix(parents: tuple[int, ...]) -> Tensor:
    """(J, J) 0/1 matrix: row n marks the joints whose offsets add up to n's rest position."""
    return torch.tensor(ancestor_matrix(parents), dtype=torch.float32)


def _check_motion(local_quats: Tensor, root_pos: Tensor, offsets: Tensor) -> None:
    if local_quats.ndim != 4 or local_quats.shape[-1] != 4:
        raise ValueError(f"local_quats must be (B, T, J, 4), got {tuple(local_quats.shape)}")
    b, t, j, _ = local_quats.shape
    if tuple(root_pos.shape) != (b, t, 3):
        raise ValueError(f"root_pos must be ({b}, {t}, 3), got {tuple(root_pos.shape)}")
    if tuple(offsets.shape) != (b, j, 3):
        raise ValueError(f"offsets must be ({b}, {j}, 3), got {tuple(offsets.shape)}")


@torch.inference_mode(False)
def _quat_to_matrix_table() -> Tensor:
    """(16, 9) table T with R(q).flatten() = (q qᵀ).flatten() @ T for unit quaternions q."""
    return torch.tensor(matrix_table(), dtype=torch.float32)


class FrameKinematics:
    """Forward kinematics of single frames in few large tensor ops (online path, NKN decoder).

    Same convention and result as :func:`robot_retarget.nn.fk_torch.forward_kinematics` (tested
    equal, values and gradients), organised for one frame at a time: rotations become matrices
    with one matmul, global rotations come from *pointer jumping* (log₂ depth rounds of
    ``G_n ← G_anc(n) · G_n``, 3 for the canonical tree) and positions from one product of the
    bone vectors with the 0/1 ancestor matrix. One frame costs ~15 tensor ops instead of ~200.
    The matrices use the quadratic form that holds for *unit* quaternions: normalise network
    outputs first (gradients then agree with the FK layer's, tested).
    """

    @torch.inference_mode(False)
    def __init__(self, parents: Sequence[int] = CANONICAL_PARENTS) -> None:
        j = len(parents)
        self.num_joints = j
        # Index j is a sentinel "parent of the root" holding the identity.
        jumps = pointer_jumps(parents)
        self._jumps = [torch.tensor(a) for a in jumps]
        self._parent = torch.tensor(jumps[0][:j])
        self._chain = _ancestor_matrix(tuple(parents))
        self._table = _quat_to_matrix_table()

    def matrices(self, quats: Tensor) -> Tensor:
        """Rotation matrices (B, J, 3, 3) of unit quaternions (B, J, 4)."""
        outer = (quats[..., :, None] * quats[..., None, :]).flatten(-2)
        return (outer @ self._table.to(quats)).view(*quats.shape[:-1], 3, 3)

    def positions(
        self, quats: Tensor, offsets: Tensor, root_rot: Tensor | None = None
    ) -> tuple[Tensor, Tensor]:
        """Joint positions (B, J, 3) relative to the root and the root's matrix (B, 3, 3).

        ``root_rot`` (B, 3, 3), when given, replaces the root's rotation.
        """
        rot = self.matrices(quats)
        if root_rot is not None:
            rot = torch.cat([root_rot[:, None], rot[:, 1:]], dim=1)
        eye = torch.eye(3, dtype=rot.dtype, device=rot.device).expand(rot.shape[0], 1, 3, 3)
        glob = torch.cat([rot, eye], dim=1)
        for anc in self._jumps:
            glob = glob[:, anc.to(rot.device)] @ glob
        bones = (glob[:, self._parent.to(rot.device)] @ offsets[..., None])[..., 0]
        return self._chain.to(bones) @ bones, rot[:, 0]


def _unyaw_matrices(yaw_rad: Tensor) -> Tensor:
    """Matrices (B, 3, 3) rotating by −yaw_rad (B,) about Y (removing a heading)."""
    c = torch.cos(yaw_rad)
    s = torch.sin(yaw_rad)
    zero = torch.zeros_like(c)
    one = torch.ones_like(c)
    return torch.stack([c, zero, -s, zero, one, zero, s, zero, c], dim=-1).view(-1, 3, 3)


@dataclass(frozen=True)
class FrameFeatures:
    """One frame of :class:`MotionFeatures` (the online path).

    ``source_quats`` are the frame's rotations as given (root entry with heading); the
    heading-free ``local_quats`` are derived on demand (only the copy baselines need them).
    """

    local_pos: Tensor  # (B, J, 3)
    root_vel: Tensor  # (B, 4)
    source_quats: Tensor  # (B, J, 4)
    yaw: Tensor  # (B,)

    @property
    def local_quats(self) -> Tensor:
        """Rotations (B, J, 4) with the heading removed from the root entry."""
        return remove_heading(self.source_quats, self.yaw)


class FeatureStream:
    """Causal, frame-by-frame features of a live source, and integration of the output root.

    ``push`` turns one source frame into features (identical to :func:`compute_features` on the
    clip up to that frame); ``integrate`` turns one predicted root velocity into the target's
    root position and heading, starting from the source's first position and heading (as
    :func:`integrate_root`).
    """

    def __init__(self, parents: Sequence[int] = CANONICAL_PARENTS) -> None:
        self.parents = tuple(parents)
        self._fk = FrameKinematics(self.parents)
        self.reset()

    def reset(self) -> None:
        """Forget the previous frame: the next push is frame 0."""
        self._prev_pos: Tensor | None = None
        self._prev_yaw: Tensor | None = None
        self._out_pos: Tensor | None = None
        self._out_yaw: Tensor | None = None
        self._first = True

    def push(self, local_quats: Tensor, root_pos: Tensor, offsets: Tensor) -> FrameFeatures:
        """Features of one frame: ``local_quats`` (B, J, 4), ``root_pos`` (B, 3), offsets."""
        _check_motion(local_quats[:, None], root_pos[:, None], offsets)
        # Heading from the root's +X column (hips' left-right axis), as heading_yaw; removing
        # it from the root matrix before FK gives heading-free positions directly.
        root_rot = self._fk.matrices(local_quats[:, 0])
        yaw = torch.atan2(-root_rot[:, 2, 0], root_rot[:, 0, 0])
        unyaw = _unyaw_matrices(yaw)
        local, _ = self._fk.positions(local_quats, offsets, unyaw @ root_rot)
        if self._prev_pos is None or self._prev_yaw is None:
            vel = root_pos.new_zeros(root_pos.shape[0], ROOT_VEL_DIM)
            self._out_pos, self._out_yaw = root_pos, yaw
        else:
            disp = unyaw @ (root_pos - self._prev_pos)[..., None]
            vel = torch.cat([disp[..., 0], wrap_angle(yaw - self._prev_yaw)[:, None]], dim=-1)
        self._prev_pos, self._prev_yaw = root_pos, yaw
        return FrameFeatures(local_pos=local, root_vel=vel, source_quats=local_quats, yaw=yaw)

    def integrate(self, root_vel: Tensor) -> tuple[Tensor, Tensor]:
        """Target root position (B, 3) and heading (B,) after one predicted velocity (B, 4)."""
        if self._out_pos is None or self._out_yaw is None:
            raise RuntimeError("FeatureStream.integrate called before push")
        if self._first:
            # Frame 0's velocity is ignored, as in integrate_root.
            self._first = False
            return self._out_pos, self._out_yaw
        yaw = self._out_yaw + root_vel[:, 3]
        pos = self._out_pos + yaw_rotate(root_vel[:, :3], yaw)
        self._out_pos, self._out_yaw = pos, yaw
        return pos, yaw
