"""Differentiable robot forward kinematics in torch, the twin of ``robot.kinematics``.

Same chain, same rule (``T_child = T_parent · T_origin · Rot(axis, q)``, fixed frames hang from
links), same frame order (links parent-first, then fixed frames), built from the numpy
:class:`~robot_retarget.robot.kinematics.KinematicChain`, so the two agree to rounding. The
chain constants are buffers: ``module.to(dtype=torch.float32)`` or ``.to(device)`` moves them.
Joint angles (…, J) in config joint order, any leading dimensions; gradients flow to ``q`` (and
to ``root_transform``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import torch

from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import KinematicChain

Tensor = torch.Tensor


class RobotFK(torch.nn.Module):
    """Batched, differentiable FK of one robot config."""

    origin_pos: Tensor
    origin_rot: Tensor
    rot_k: Tensor
    rot_k2: Tensor
    frame_pos: Tensor
    frame_rot: Tensor
    link_joint: Tensor
    frame_parent: Tensor

    def __init__(self, config: RobotConfig, dtype: torch.dtype = torch.float64) -> None:
        super().__init__()
        chain = KinematicChain.from_config(config)
        self.num_joints = config.num_joints
        self.link_names = chain.link_names
        self.frame_names = chain.frame_names
        self._link_parent = tuple(int(p) for p in chain.link_parent)
        self._index = {n: i for i, n in enumerate(self.frame_names)}

        def buf(name: str, value: npt.NDArray[np.float64]) -> None:
            # np.array copies: the chain's arrays are read-only, torch wants writable memory.
            self.register_buffer(name, torch.tensor(np.array(value), dtype=dtype))

        buf("origin_pos", chain.origin_pos)
        buf("origin_rot", chain.origin_rot)
        buf("rot_k", chain.rot_k)
        buf("rot_k2", chain.rot_k2)
        buf("frame_pos", chain.frame_pos)
        buf("frame_rot", chain.frame_rot)
        self.register_buffer("link_joint", torch.tensor(np.array(chain.link_joint)))
        self.register_buffer("frame_parent", torch.tensor(np.array(chain.frame_parent)))

    def frame_index(self, names: Sequence[str]) -> list[int]:
        """Indices of frames by name; KeyError lists the frames that exist."""
        try:
            return [self._index[n] for n in names]
        except KeyError as exc:
            raise KeyError(f"no frame {exc.args[0]!r}; frames: {self.frame_names}") from None

    def link_poses(self, q: Tensor, root_transform: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Link rotations (…, L, 3, 3) and positions (…, L, 3)."""
        if q.shape[-1:] != (self.num_joints,):
            raise ValueError(
                f"joint angles need a last axis of {self.num_joints}, got shape {tuple(q.shape)}"
            )
        lead = q.shape[:-1]
        qj = q[..., self.link_joint]  # (…, L-1) in link order
        s = torch.sin(qj)[..., None, None]
        vc = (1.0 - torch.cos(qj))[..., None, None]
        local = self.origin_rot + s * self.rot_k + vc * self.rot_k2  # (…, L-1, 3, 3)
        if root_transform is None:
            root_rot = torch.eye(3, dtype=q.dtype, device=q.device).expand(*lead, 3, 3)
            root_pos = torch.zeros(*lead, 3, dtype=q.dtype, device=q.device)
        else:
            if root_transform.shape[-2:] != (4, 4):
                raise ValueError(
                    f"root_transform must have shape (..., 4, 4), got {tuple(root_transform.shape)}"
                )
            root_rot = root_transform[..., :3, :3].expand(*lead, 3, 3)
            root_pos = root_transform[..., :3, 3].expand(*lead, 3)
        rots = [root_rot]
        poss = [root_pos]
        for k, p in enumerate(self._link_parent):
            r_parent = rots[p]
            poss.append(poss[p] + (r_parent @ self.origin_pos[k, :, None])[..., 0])
            rots.append(r_parent @ local[..., k, :, :])
        return torch.stack(rots, dim=-3), torch.stack(poss, dim=-2)

    def frame_poses(
        self,
        q: Tensor,
        frames: Sequence[str] | None = None,
        root_transform: Tensor | None = None,
    ) -> tuple[Tensor, Tensor]:
        """Rotations (…, F, 3, 3) and positions (…, F, 3) of the named frames (all by default)."""
        link_rot, link_pos = self.link_poses(q, root_transform)
        parent_rot = link_rot[..., self.frame_parent, :, :]
        fixed_rot = parent_rot @ self.frame_rot
        fixed_pos = (
            link_pos[..., self.frame_parent, :] + (parent_rot @ self.frame_pos[..., None])[..., 0]
        )
        rot = torch.cat([link_rot, fixed_rot], dim=-3)
        pos = torch.cat([link_pos, fixed_pos], dim=-2)
        if frames is None:
            return rot, pos
        idx = torch.as_tensor(self.frame_index(frames), dtype=torch.long, device=q.device)
        return rot[..., idx, :, :], pos[..., idx, :]

    def frame_positions(
        self,
        q: Tensor,
        frames: Sequence[str] | None = None,
        root_transform: Tensor | None = None,
    ) -> Tensor:
        """Positions (…, F, 3) of the named frames (all ``frame_names`` by default)."""
        return self.frame_poses(q, frames, root_transform)[1]

    def frame_rotations(
        self,
        q: Tensor,
        frames: Sequence[str] | None = None,
        root_transform: Tensor | None = None,
    ) -> Tensor:
        """Rotation matrices (…, F, 3, 3) of the named frames (all ``frame_names`` by default)."""
        return self.frame_poses(q, frames, root_transform)[0]

    def forward(self, q: Tensor) -> tuple[Tensor, Tensor]:
        """(rotations (…, F, 3, 3), positions (…, F, 3)) of every frame."""
        return self.frame_poses(q)
