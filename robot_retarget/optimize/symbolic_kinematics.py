"""The robot's forward kinematics as CasADi SX expressions of the joint angles.

Built straight from the RobotConfig dataclasses (URDF semantics): a joint's child link sits at
``T_parent · T_origin(xyz, rpy) · Rot(axis, q)``; a fixed frame at ``T_parent_link · T_origin``.
Everything is expressed in the root link frame. SX (not MX) because the optimizer expands the
whole problem into one flat expression graph, which is what makes the JIT-compiled solve fast.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ConfigError
from robot_retarget.robot.config import RobotConfig, Vec3

Pose = tuple[ca.SX, ca.SX]  # (rotation 3×3, position 3×1) in the root frame


def rpy_matrix(rpy: Vec3) -> FloatArray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) · Ry(pitch) · Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(rz @ ry @ rx, dtype=np.float64)


def _axis_rotation(axis: Vec3, angle: ca.SX) -> ca.SX:
    """Rodrigues' formula; zero axis components vanish from the SX graph (x·0 folds to 0)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    c = ca.cos(angle)
    s = ca.sin(angle)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    kk = k @ k
    rot = ca.SX(3, 3)
    for i in range(3):
        for j in range(3):
            # Skip exact zeros so the expression graph stays minimal.
            term: ca.SX = ca.SX(1.0 if i == j else 0.0)
            if k[i, j] != 0.0:
                term = term + s * k[i, j]
            if kk[i, j] != 0.0:
                term = term + (1.0 - c) * kk[i, j]
            rot[i, j] = term
    return rot


class SymbolicKinematics:
    """Root-frame poses of every link and fixed frame as SX functions of ``q`` (J,)."""

    def __init__(self, config: RobotConfig, q: ca.SX) -> None:
        self.config = config
        self.q = q
        self._joint_of_child = {j.child_link: i for i, j in enumerate(config.joints)}
        self._fixed = {f.name: f for f in config.frames}
        self._cache: dict[str, Pose] = {config.root_link: (ca.SX.eye(3), ca.SX.zeros(3, 1))}

    def frame_names(self) -> tuple[str, ...]:
        """Every name ``pose`` accepts: root link, joint child links, fixed frames."""
        return (
            self.config.root_link,
            *(j.child_link for j in self.config.joints),
            *(f.name for f in self.config.frames),
        )

    def carrier_link(self, frame: str) -> str:
        """The link that carries a frame's *origin*: a child link's origin lies on its joint
        axis, so it is fixed in the parent link; a fixed frame's in its own parent link."""
        if frame in self._fixed:
            return self._fixed[frame].parent_link
        if frame in self._joint_of_child:
            return self.config.joints[self._joint_of_child[frame]].parent_link
        return frame

    def pose(self, frame: str) -> Pose:
        """(R, p) of a link or fixed frame in the root frame."""
        if frame in self._cache:
            return self._cache[frame]
        if frame in self._fixed:
            f = self._fixed[frame]
            r_parent, p_parent = self.pose(f.parent_link)
            pose = (
                r_parent @ ca.SX(rpy_matrix(f.origin_rpy)),
                p_parent + r_parent @ ca.SX(np.asarray(f.origin_xyz)),
            )
        elif frame in self._joint_of_child:
            i = self._joint_of_child[frame]
            j = self.config.joints[i]
            r_parent, p_parent = self.pose(j.parent_link)
            r_origin = r_parent @ ca.SX(rpy_matrix(j.origin_rpy))
            pose = (
                r_origin @ _axis_rotation(j.axis, self.q[i]),
                p_parent + r_parent @ ca.SX(np.asarray(j.origin_xyz)),
            )
        else:
            raise ConfigError(
                f"robot {self.config.name}: unknown frame {frame!r}",
                path=self.config.source_path,
                key="bones",
                allowed=", ".join(self.frame_names()),
            )
        self._cache[frame] = pose
        return pose

    def position(self, frame: str) -> ca.SX:
        return self.pose(frame)[1]

    def rotation(self, frame: str) -> ca.SX:
        return self.pose(frame)[0]

    def positions_function(self, frames: tuple[str, ...]) -> ca.Function:
        """Numeric helper: q (J,) → positions (3, len(frames)) in the root frame."""
        return ca.Function("frame_positions", [self.q], [ca.horzcat(*map(self.position, frames))])

    def rotations_function(self, frames: tuple[str, ...]) -> ca.Function:
        """Numeric helper: q (J,) → rotation matrices stacked as (3, 3·len(frames))."""
        return ca.Function("frame_rotations", [self.q], [ca.horzcat(*map(self.rotation, frames))])
