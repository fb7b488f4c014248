"""Turn a raw BVH clip into a HumanMotion on the canonical skeleton.

Each canonical joint takes the *global* rotation of its source joint (joint_map.py), and its
rest offset is the rest-pose position difference between the mapped source joints, so the
source joints that are not mapped (LHipJoint, Neck, fingers, …) fold into the bones. Local
rotations are then parent⁻¹ ⊗ global, after re-expressing the motion relative to the canonical
T-pose (skeleton/rest_pose.py: joint positions unchanged). Where the dropped in-between joints
never rotate, the canonical joints land exactly on their source joints.

Z-up (or any other axis-up) files are turned Y-up: with r the rotation taking the file's up
axis to +Y, positions become r·p and global rotations r ⊗ G ⊗ r*, which keeps the rest pose
the identity.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import MotionFormatError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.auto_map import TreeGeometry
from robot_retarget.motion.bvh import BvhClip
from robot_retarget.motion.human_motion import HumanMotion, standing_height
from robot_retarget.motion.joint_map import JointMap, map_joints
from robot_retarget.motion.tpose import count_synthetic_tpose_frames
from robot_retarget.motion.units import detect_unit, unit_scale_m
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS, Joint
from robot_retarget.skeleton.rest_pose import align_to_tpose
from robot_retarget.skeleton.skeleton import Skeleton, local_from_global

UP_AXES: dict[str, tuple[float, float, float]] = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}
# The head must lie this close (cosine) to one axis above the feet for the up axis to be clear.
_MIN_UP_COSINE = 0.7


def clip_geometry(clip: BvhClip) -> TreeGeometry:
    return TreeGeometry(
        clip.parents, clip.rest_positions(), clip.end_site_parents, clip.rest_end_site_positions()
    )


def detect_up_axis(points: FloatArray, joint_map: JointMap, path: str | None = None) -> str:
    """The signed axis pointing from the feet to the head in the rest pose."""
    at = joint_map.position_points
    feet = 0.5 * (points[at[Joint.LeftFoot]] + points[at[Joint.RightFoot]])
    v = points[at[Joint.Head]] - feet
    n = float(np.linalg.norm(v))
    k = int(np.argmax(np.abs(v)))
    if n == 0.0 or abs(v[k]) / n < _MIN_UP_COSINE:
        raise MotionFormatError(
            f"cannot tell which axis is up: the rest pose's feet-to-head vector is {v}; "
            "pass up_axis explicitly (e.g. 'y' or 'z')",
            path=path,
        )
    return ("" if v[k] > 0 else "-") + "xyz"[k]


def _up_rotation(up_axis: str) -> FloatArray:
    try:
        axis = UP_AXES[up_axis]
    except KeyError:
        raise MotionFormatError(
            f"unknown up axis {up_axis!r}; use one of {', '.join(UP_AXES)}"
        ) from None
    if up_axis == "-y":  # from_two_vectors would pick an arbitrary half-turn axis
        return np.array([0.0, 0.0, 0.0, 1.0])  # half-turn about z keeps the facing direction
    return quat.from_two_vectors(np.array(axis), np.array([0.0, 1.0, 0.0]))


def _height_units(clip: BvhClip, points: FloatArray, jm: JointMap) -> float:
    """Standing height in file units, points already turned Y-up."""
    num = clip.num_joints
    subtree: dict[int, list[int]] = {}

    def points_below(j: int) -> list[int]:
        if j not in subtree:
            kids = [c for c, p in enumerate(clip.parents) if p == j]
            ends = [num + e for e, p in enumerate(clip.end_site_parents) if p == j]
            subtree[j] = [j, *ends] + [q for c in kids for q in points_below(c)]
        return subtree[j]

    at = jm.position_points
    src = jm.source_joints
    head = src[Joint.Head]
    head_top = max(
        (points[q] for q in points_below(head if head is not None else at[Joint.Head])),
        key=lambda p: float(p[1]),
    )
    sides = ("Left", "Right")
    soles = []
    for s in sides:
        foot = src[Joint[s + "Foot"]]
        below = points_below(foot) if foot is not None else [at[Joint[s + "Foot"]]]
        soles.append(min((points[q] for q in below), key=lambda p: float(p[1])))
    return standing_height(
        points[at[Joint.Hips]],
        head_top,
        [points[at[Joint[s + "UpLeg"]]] for s in sides],
        [points[at[Joint[s + "Leg"]]] for s in sides],
        [points[at[Joint[s + "Foot"]]] for s in sides],
        soles,
    )


def canonicalize(
    clip: BvhClip,
    *,
    unit: str | None = None,
    drop_tpose: bool | Literal["auto"] = "auto",
    up_axis: str | None = None,
    family: str | None = None,
) -> HumanMotion:
    """Map a BVH clip onto the canonical skeleton (see load_motion for the options)."""
    geo = clip_geometry(clip)
    jm = map_joints(clip.names, geo, family=family, path=clip.path)
    points = np.concatenate([geo.rest_joints, geo.rest_end_sites], axis=0)
    up = up_axis if up_axis is not None else detect_up_axis(points, jm, clip.path)
    r = _up_rotation(up)
    points_up = quat.rotate(r, points)

    height_units = _height_units(clip, points_up, jm)
    unit_name = unit if unit is not None else detect_unit(height_units, clip.path)
    scale = unit_scale_m(unit_name)

    dropped = 0
    if drop_tpose is not False:
        dropped = count_synthetic_tpose_frames(clip)
        if drop_tpose is True:
            dropped = max(dropped, 1)
        if dropped >= clip.num_frames:
            raise MotionFormatError(
                f"the clip has only {clip.num_frames} frame(s), all synthetic T-pose; "
                "load it with drop_tpose=False",
                path=clip.path,
            )
    body = clip.frames(dropped) if dropped else clip

    pos, rot = body.global_transforms()
    r_conj = quat.conjugate(r)
    glob = quat.mul(quat.mul(r, rot[:, list(jm.rotation_joints)]), r_conj)

    at = jm.position_points
    offsets = np.zeros((len(CANONICAL_JOINTS), 3))
    for c, p in enumerate(CANONICAL_PARENTS):
        if p >= 0:
            offsets[c] = (points_up[at[c]] - points_up[at[p]]) * scale
    skeleton = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets)
    hips = jm.source_joints[Joint.Hips]
    if hips is None:  # required joint: map_joints guarantees it
        raise MotionFormatError("the Hips joint is not mapped", path=clip.path)
    root_pos = quat.rotate(r, pos[:, hips]) * scale
    # Rotations relative to one T-pose, so they mean the same pose on every skeleton.
    skeleton, glob = align_to_tpose(skeleton, glob)
    local = local_from_global(skeleton, glob)
    return HumanMotion(
        skeleton=skeleton,
        local_quats=quat.normalize(local),
        root_pos=root_pos,
        fps=clip.fps,
        source_path=clip.path,
        name_family=jm.family,
        unit=unit_name,
        height_m=height_units * scale,
        tpose_frames_dropped=dropped,
        up_axis=up,
        source_joints=tuple(jm.source_names(clip.names).values()),
    )
