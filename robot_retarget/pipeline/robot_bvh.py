"""A robot trajectory as a BVH of the robot's own skeleton (links as joints), for Blender.

BVH joints are the robot's links (root link first, parents before children); each fixed frame
hanging from a leaf link (hand point, sole, …) becomes that link's End Site. Axes are the BVH
convention (Y up, facing +Z): robot root-frame vectors are turned by the config's up / forward
axes. The rest pose is the robot's zero pose, so a link's BVH rotation is its posed world
rotation times its zero-pose rotation transposed, and rest offsets are zero-pose position
differences; this reproduces every link position exactly. The root moves with the
trajectory's ``root_pos`` / ``root_quat`` when present: the base link's pose in the robot's
Z-up, x-forward world (as convert writes it), turned into BVH axes (world x → BVH Z, y → X,
z → Y). The root's rotation channels are Y X Z (heading first): a performer who turns
(a pirouette) passes heading ±90° all the time, which in Z Y X order — heading in the middle —
is gimbal lock, where a tiny tilt swings the other two angles by up to 180°; Y X Z locks only
with the body horizontal. Links keep Z Y X. Euler angles are kept continuous from frame to
frame (of the two triples of a rotation, and their 2π turns, the one nearest the previous
frame's), so players that interpolate channels never spin a joint the long way round. Lengths
in metres (Blender's BVH import scale 1.0 gives metres).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import euler
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import BvhClip, write_bvh
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.canonical_skeleton import robot_to_canonical_rotation
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics

_ROOT_ORDER = "YXZ"  # heading first: no gimbal lock while the performer turns
_JOINT_ORDER = "ZYX"
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", *(f"{a}rotation" for a in _ROOT_ORDER))
_JOINT_CHANNELS = tuple(f"{a}rotation" for a in _JOINT_ORDER)


# The robot's world (x forward, y left, z up) in BVH axes (X left, Y up, Z forward).
WORLD_TO_BVH = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def continuous_euler(angles_rad: FloatArray) -> FloatArray:
    """Tait–Bryan Euler angles (T, …, 3) of any order (ZYX, YXZ, …) made continuous along T:
    per frame the equivalent triple (a, b, c) or (a + π, π − b, c + π), shifted by whole turns,
    nearest the previous frame's."""
    out = np.array(angles_rad, dtype=np.float64, copy=True)
    two_pi = 2.0 * np.pi
    for t in range(1, len(out)):
        prev = out[t - 1]
        a = out[t]
        b = a + np.array([np.pi, 0.0, np.pi])
        b[..., 1] = np.pi - a[..., 1]
        a = a + two_pi * np.round((prev - a) / two_pi)
        b = b + two_pi * np.round((prev - b) / two_pi)
        use_b = np.abs(b - prev).sum(axis=-1) < np.abs(a - prev).sum(axis=-1)
        out[t] = np.where(use_b[..., None], b, a)
    return out


def robot_bvh_clip(config: RobotConfig, trajectory: RobotTrajectory) -> BvhClip:
    """The BvhClip of ``trajectory`` (joint order must match the config)."""
    if trajectory.joint_names != config.joint_names:
        raise ValueError(
            f"trajectory joints {trajectory.joint_names} do not match robot {config.name}'s "
            f"{config.joint_names}"
        )
    kin = RobotKinematics(config)
    c = robot_to_canonical_rotation(config)  # root-frame vectors → BVH axes
    chain = kin.chain
    n_links = len(chain.link_names)
    # BVH files list joints depth-first and their channels in that order: reorder the links.
    chain_parents = (-1, *(int(p) for p in chain.link_parent))
    order = _depth_first(chain_parents)
    new_index = {old: new for new, old in enumerate(order)}
    parents = tuple(-1 if chain_parents[o] < 0 else new_index[chain_parents[o]] for o in order)
    names = tuple(chain.link_names[o] for o in order)
    rest = kin.link_transforms(np.zeros(config.num_joints))[order]
    rest_rot = c @ rest[:, :3, :3]  # (L, 3, 3)
    rest_pos = rest[:, :3, 3] @ c.T
    offsets = np.zeros((n_links, 3))
    for k in range(1, n_links):
        offsets[k] = rest_pos[k] - rest_pos[parents[k]]
    posed = kin.link_transforms(trajectory.q)[:, order]  # (T, L, 4, 4)
    glob = c @ posed[..., :3, :3] @ np.swapaxes(rest_rot, -1, -2)  # (T, L, 3, 3)
    if trajectory.root_quat is not None:
        # World (Z up) → BVH axes, of the base link's rotation as seen from its BVH rest frame.
        root_rot = WORLD_TO_BVH @ quat.to_matrix(trajectory.root_quat) @ c.T
        glob = root_rot[:, None] @ glob
    local = glob.copy()
    for k in range(1, n_links):
        local[:, k] = np.swapaxes(glob[:, parents[k]], -1, -2) @ glob[:, k]
    local_q = quat.from_matrix(local)  # (T, L, 4)
    angles = np.empty((trajectory.num_frames, n_links, 3))
    angles[:, 0] = euler.to_euler(local_q[:, 0], _ROOT_ORDER)
    angles[:, 1:] = euler.to_euler(local_q[:, 1:], _JOINT_ORDER)
    angles = np.degrees(continuous_euler(angles))
    root_pos = (
        trajectory.root_pos @ WORLD_TO_BVH.T
        if trajectory.root_pos is not None
        else np.zeros((trajectory.num_frames, 3))
    )
    motion = np.concatenate([root_pos, angles.reshape(trajectory.num_frames, -1)], axis=1)
    leaves = [k for k in range(n_links) if k not in parents]
    end_parents: list[int] = []
    end_offsets: list[FloatArray] = []
    for f, chain_parent in enumerate(chain.frame_parent):
        parent = new_index[int(chain_parent)]
        if parent in leaves and parent not in end_parents:
            end_parents.append(parent)
            end_offsets.append(rest_rot[parent] @ chain.frame_pos[f])
    for k in leaves:  # a visible tip for leaves without a fixed frame
        if k not in end_parents:
            end_parents.append(k)
            end_offsets.append(np.array([0.0, 0.01, 0.0]))
    return BvhClip(
        names=names,
        parents=parents,
        offsets=offsets,
        channels=(_ROOT_CHANNELS, *([_JOINT_CHANNELS] * (n_links - 1))),
        end_site_parents=tuple(end_parents),
        end_site_offsets=np.array(end_offsets).reshape(-1, 3),
        frame_time_s=1.0 / trajectory.fps,
        motion=motion,
        path=None,
    )


def _depth_first(parents: tuple[int, ...]) -> list[int]:
    children: dict[int, list[int]] = {}
    for k, p in enumerate(parents):
        children.setdefault(p, []).append(k)
    out: list[int] = []
    stack = list(reversed(children.get(-1, [])))
    while stack:
        k = stack.pop()
        out.append(k)
        stack.extend(reversed(children.get(k, [])))
    return out


def write_robot_bvh(
    path: str | Path, config: RobotConfig, trajectory: RobotTrajectory, *, overwrite: bool = False
) -> Path:
    """Write the robot BVH; refuses to replace a file unless ``overwrite``."""
    return write_bvh(path, robot_bvh_clip(config, trajectory), overwrite=overwrite)
