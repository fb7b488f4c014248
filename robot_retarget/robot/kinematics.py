"""Robot forward kinematics in numpy, built once from a :class:`RobotConfig`.

Each link's pose in the root link frame follows the URDF rule

    T_child = T_parent · T_origin(xyz, rpy) · Rot(axis, q)

and a fixed frame is ``T_link · T_origin(xyz, rpy)``. The constructor orders links
parent-first and precomputes, per joint, the origin rotation ``R0`` and the products ``R0·K`` and
``R0·K²`` of Rodrigues' formula (``K`` the axis' cross-product matrix), so a call builds all
joint transforms at once with ``R0·Rot(q) = R0 + sin q · R0K + (1 − cos q) · R0K²`` and then
runs one tight loop of 4×4 products over the links.

Frames are named: every link (root first, then in parent-first order) and then every fixed
frame of the config. All functions take joint angles ``q`` of shape (…, J) in the config's joint
order and return arrays over the same leading dimensions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.geometry.euler import matrix_from_euler
from robot_retarget.robot.config import RobotConfig

_PROBE_RAD = 0.1  # the turn that tells which frames a joint carries (carried_frames)
_CARRIES_M = 1e-6  # … a frame it moves further than this


@dataclass(frozen=True)
class KinematicChain:
    """The precomputed chain, shared by the numpy and torch implementations.

    Links are in parent-first order; link 0 is the root. For link ``k ≥ 1``:
    ``link_parent[k-1]`` is its parent link index, ``link_joint[k-1]`` the index of its joint in
    the config's joint order, ``origin_pos[k-1]`` / ``origin_rot[k-1]`` the joint origin in the
    parent link frame, ``rot_k[k-1] = R0·K`` and ``rot_k2[k-1] = R0·K²``. Fixed frame ``f`` hangs
    from link ``frame_parent[f]`` at ``frame_pos[f]`` / ``frame_rot[f]``.
    """

    link_names: tuple[str, ...]
    link_parent: IntArray  # (L-1,)
    link_joint: IntArray  # (L-1,)
    origin_pos: FloatArray  # (L-1, 3)
    origin_rot: FloatArray  # (L-1, 3, 3)
    rot_k: FloatArray  # (L-1, 3, 3)
    rot_k2: FloatArray  # (L-1, 3, 3)
    fixed_names: tuple[str, ...]
    frame_parent: IntArray  # (F_fixed,)
    frame_pos: FloatArray  # (F_fixed, 3)
    frame_rot: FloatArray  # (F_fixed, 3, 3)

    @property
    def frame_names(self) -> tuple[str, ...]:
        return self.link_names + self.fixed_names

    @classmethod
    def from_config(cls, config: RobotConfig) -> KinematicChain:
        by_parent: dict[str, list[int]] = {}
        for i, j in enumerate(config.joints):
            by_parent.setdefault(j.parent_link, []).append(i)
        link_names = [config.root_link]
        parents: list[int] = []
        order: list[int] = []
        # Breadth-first from the root; the loader guarantees one tree, so every joint is reached.
        k = 0
        while k < len(link_names):
            for i in by_parent.get(link_names[k], []):
                order.append(i)
                parents.append(k)
                link_names.append(config.joints[i].child_link)
            k += 1
        joints = [config.joints[i] for i in order]
        r0 = _rpy_matrices([j.origin_rpy for j in joints])
        skew = np.array([_skew(np.asarray(j.axis, dtype=np.float64)) for j in joints])
        skew = skew.reshape(-1, 3, 3)
        rot_k = r0 @ skew
        index = {n: i for i, n in enumerate(link_names)}
        chain = cls(
            link_names=tuple(link_names),
            link_parent=np.array(parents, dtype=np.int64),
            link_joint=np.array(order, dtype=np.int64),
            origin_pos=np.array([j.origin_xyz for j in joints], dtype=np.float64).reshape(-1, 3),
            origin_rot=r0,
            rot_k=rot_k,
            rot_k2=rot_k @ skew,
            fixed_names=tuple(f.name for f in config.frames),
            frame_parent=np.array([index[f.parent_link] for f in config.frames], dtype=np.int64),
            frame_pos=np.array([f.origin_xyz for f in config.frames], dtype=np.float64).reshape(
                -1, 3
            ),
            frame_rot=_rpy_matrices([f.origin_rpy for f in config.frames]),
        )
        for a in (chain.origin_pos, chain.origin_rot, chain.rot_k, chain.rot_k2):
            a.setflags(write=False)
        return chain


class RobotKinematics:
    """Forward kinematics of one robot config (numpy, batched over leading dimensions)."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        self.chain = KinematicChain.from_config(config)
        self._index = {n: i for i, n in enumerate(self.chain.frame_names)}
        self._fixed = homogeneous(self.chain.frame_rot, self.chain.frame_pos)  # (F_fixed, 4, 4)

    @property
    def num_joints(self) -> int:
        return self.config.num_joints

    @property
    def link_names(self) -> tuple[str, ...]:
        return self.chain.link_names

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Every named frame: the links (root first, parent-first order), then fixed frames."""
        return self.chain.frame_names

    def frame_index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(
                f"robot {self.config.name} has no frame {name!r}; frames: {self.frame_names}"
            ) from None

    def frame_indices(self, frames: Sequence[str] | None) -> IntArray:
        if frames is None:
            return np.arange(len(self.frame_names), dtype=np.int64)
        if isinstance(frames, str):
            raise TypeError("frames must be a sequence of frame names, not one string")
        return np.array([self.frame_index(f) for f in frames], dtype=np.int64)

    def link_transforms(
        self, q: npt.ArrayLike, root_transform: npt.ArrayLike | None = None
    ) -> FloatArray:
        """Homogeneous transforms (…, L, 4, 4) of the links, in ``link_names`` order, in the root
        frame (or the world frame given ``root_transform`` (…, 4, 4), the root link's pose)."""
        q = self._joint_angles(q)
        c = self.chain
        lead = q.shape[:-1]
        s = np.sin(q)[..., c.link_joint, None, None]
        vc = (1.0 - np.cos(q))[..., c.link_joint, None, None]
        local = np.zeros((*lead, len(c.link_joint), 4, 4))
        local[..., :3, :3] = c.origin_rot + s * c.rot_k + vc * c.rot_k2
        local[..., :3, 3] = c.origin_pos
        local[..., 3, 3] = 1.0
        out = np.empty((*lead, len(c.link_names), 4, 4))
        if root_transform is None:
            out[..., 0, :, :] = np.eye(4)
        else:
            root = np.asarray(root_transform, dtype=np.float64)
            if root.shape[-2:] != (4, 4):
                raise ValueError(f"root_transform must have shape (..., 4, 4), got {root.shape}")
            out[..., 0, :, :] = root
        # One 4×4 product per link, parents first.
        for k, p in enumerate(c.link_parent, start=1):
            np.matmul(out[..., p, :, :], local[..., k - 1, :, :], out=out[..., k, :, :])
        return out

    def link_poses(
        self, q: npt.ArrayLike, root_transform: npt.ArrayLike | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Link rotations (…, L, 3, 3) and positions (…, L, 3); see :meth:`link_transforms`."""
        t = self.link_transforms(q, root_transform)
        return t[..., :3, :3], t[..., :3, 3]

    def frame_transforms(
        self,
        q: npt.ArrayLike,
        frames: Sequence[str] | None = None,
        root_transform: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Homogeneous transforms (…, F, 4, 4) of the named frames (all ``frame_names`` by
        default, links first, then fixed frames)."""
        links = self.link_transforms(q, root_transform)
        fixed = links[..., self.chain.frame_parent, :, :] @ self._fixed
        out = np.concatenate([links, fixed], axis=-3)
        if frames is None:
            return out
        return out[..., self.frame_indices(frames), :, :]

    def frame_poses(
        self,
        q: npt.ArrayLike,
        frames: Sequence[str] | None = None,
        root_transform: npt.ArrayLike | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Rotations (…, F, 3, 3) and positions (…, F, 3) of the named frames (all by default)."""
        t = self.frame_transforms(q, frames, root_transform)
        return t[..., :3, :3], t[..., :3, 3]

    def frame_positions(
        self,
        q: npt.ArrayLike,
        frames: Sequence[str] | None = None,
        root_transform: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Positions (…, F, 3) in metres of the named frames (all ``frame_names`` by default)."""
        return self.frame_poses(q, frames, root_transform)[1]

    def frame_rotations(
        self,
        q: npt.ArrayLike,
        frames: Sequence[str] | None = None,
        root_transform: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Rotation matrices (…, F, 3, 3) of the named frames (all ``frame_names`` by default)."""
        return self.frame_poses(q, frames, root_transform)[0]

    def carried_frames(self, frames: Sequence[str] | None = None) -> npt.NDArray[np.bool_]:
        """(J, F) whether each joint alone, turned by 0.1 rad from the zero pose, moves each
        named frame (all ``frame_names`` by default) further than 1 µm: the frames it carries.
        One batched forward kinematics."""
        n = self.num_joints
        poses = np.vstack([np.zeros(n), _PROBE_RAD * np.eye(n)])
        positions = self.frame_positions(poses, frames)
        return np.asarray(np.linalg.norm(positions[1:] - positions[0], axis=-1) > _CARRIES_M)

    def _joint_angles(self, q: npt.ArrayLike) -> FloatArray:
        a = np.asarray(q, dtype=np.float64)
        if a.shape[-1:] != (self.num_joints,):
            raise ValueError(
                f"joint angles need a last axis of {self.num_joints} ({self.config.name} joints "
                f"in config order), got shape {a.shape}"
            )
        return a


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rpy_matrices(rpys: Sequence[tuple[float, float, float]]) -> FloatArray:
    """URDF rpy (fixed-axis x, y, z) → rotation matrices (N, 3, 3)."""
    if not rpys:
        return np.zeros((0, 3, 3))
    return matrix_from_euler(np.array(rpys, dtype=np.float64), "xyz")


def homogeneous(rot: FloatArray, pos: FloatArray) -> FloatArray:
    """Homogeneous transforms (…, 4, 4) from rotations (…, 3, 3) and positions (…, 3)."""
    out = np.zeros((*rot.shape[:-2], 4, 4))
    out[..., :3, :3] = rot
    out[..., :3, 3] = pos
    out[..., 3, 3] = 1.0
    return out
