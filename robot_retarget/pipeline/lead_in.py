"""A file's lead-in: the robot's move from its init pose into the clip's first frame.

``convert --lead-in`` prepends this move (stamped before t = 0) so that a player can start the
robot where it stands. The joints move at a fraction of their velocity limits
(:func:`lead_in`); the base (:func:`lead_in_base`) starts upright, facing where the clip's first
frame faces, turns into that frame's lean as the joints move, and keeps the feet on the
ground: each frame's lowest foot point at the floor (at the first frame's height above it, a
share that grows with the move, when the clip starts in the air), and the feet that stand in
the first frame centred where they stand then, so the robot neither floats nor slides across
the floor while it gets into position.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.optimize.bone_model import body_to_root
from robot_retarget.pipeline.floating_base import CONTACT_M, foot_points
from robot_retarget.pipeline.start_ramp import toward
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics


def lead_in(config: RobotConfig, q_first: FloatArray, step_rad: FloatArray) -> FloatArray:
    """(K, J) commands from the init pose (excluded) to just before ``q_first``, each joint
    moving at most ``step_rad`` per frame: the robot's move into a file's first frame."""
    out = []
    q = np.array(config.init_pose, dtype=np.float64)
    while np.any(np.abs(q_first - q) > step_rad):
        q = toward(q, q_first, step_rad)
        out.append(q)
    return np.array(out).reshape(-1, config.num_joints)


def upright_rotation(config: RobotConfig, base_rotation: npt.ArrayLike) -> FloatArray:
    """(3, 3) the base's orientation standing upright (its up axis along world z) and facing
    the heading of ``base_rotation`` (root-frame vectors → world, Z up)."""
    body = body_to_root(config)
    world_body = np.asarray(base_rotation, dtype=np.float64) @ body  # forward, left, up
    forward = world_body[:, 0] * np.array([1.0, 1.0, 0.0])
    # Leaning 90° (the forward axis vertical), the left axis still gives the heading.
    from_left = np.cross(world_body[:, 1] * np.array([1.0, 1.0, 0.0]), [0.0, 0.0, 1.0])
    if np.linalg.norm(from_left) > np.linalg.norm(forward):
        forward = from_left
    forward = forward / max(float(np.linalg.norm(forward)), 1e-12)
    up = np.array([0.0, 0.0, 1.0])
    return np.asarray(np.column_stack([forward, np.cross(up, forward), up]) @ body.T)


def lead_in_base(
    config: RobotConfig,
    q_lead: npt.ArrayLike,
    q_first: npt.ArrayLike,
    pos_first: npt.ArrayLike,
    quat_first: npt.ArrayLike,
    *,
    contact_m: float = CONTACT_M,
) -> tuple[FloatArray, FloatArray]:
    """The base's world pose (K, 3) and (K, 4) w-x-y-z over the lead-in's joint angles
    ``q_lead`` (K, J), which end just before the clip's first frame: angles ``q_first`` (J,) on a
    base at ``pos_first`` (3,) / ``quat_first`` (4,) (Z up, metres).

    The orientation turns from upright (:func:`upright_rotation`) into the first frame's at an
    even pace; each frame's lowest foot point is at the floor, raised by the share of the move
    made times the first frame's own lowest point's height; the foot points on the ground in
    the first frame (within ``contact_m`` of its lowest) keep their centre where it is then."""
    lead = np.asarray(q_lead, dtype=np.float64).reshape(-1, config.num_joints)
    k = len(lead)
    if k == 0:
        return np.empty((0, 3)), np.empty((0, 4))
    turned = np.asarray(quat_first, dtype=np.float64)
    rot_first = quat.to_matrix(turned)
    upright = quat.from_matrix(upright_rotation(config, rot_first))
    share = np.arange(1, k + 1) / (k + 1)  # of the move made at each lead-in frame
    quats = quat.slerp(upright, turned, share)  # the shorter way round…
    quats = quats * np.sign(float(quats[-1] @ turned) or 1.0)  # …on the first frame's sign
    rots = quat.to_matrix(quats)

    kin = RobotKinematics(config)
    points = list(foot_points(config))
    first_row = np.asarray(q_first, dtype=np.float64)[None]
    first_world = kin.frame_positions(first_row, points)[0] @ rot_first.T + np.asarray(
        pos_first, dtype=np.float64
    )  # (F, 3)
    floor_first = float(first_world[:, 2].min())
    standing = first_world[:, 2] <= floor_first + contact_m
    centre = first_world[standing, :2].mean(axis=0)

    rel = np.einsum("kij,kfj->kfi", rots, kin.frame_positions(lead, points))  # (K, F, 3)
    pos = np.empty((k, 3))
    pos[:, :2] = centre - rel[:, standing, :2].mean(axis=1)
    pos[:, 2] = share * floor_first - rel[:, :, 2].min(axis=1)
    return pos, quats
