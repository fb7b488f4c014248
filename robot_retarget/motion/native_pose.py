"""A BVH clip's pose on its own skeleton, as armatures (what SAN's per-skeleton encoders read).

The canonical map (canonicalize.py) folds every source onto the 22 canonical joints. A
skeleton-aware network instead reads the file's own joints: every joint on the paths from the
root to the five end-effectors keeps its own rotation, in the file's own rest pose, so a
31-joint MotionBuilder skeleton and a 43-joint DAZ skeleton are two topologies
(robot_retarget.skeleton.armatures). The joint map is used only to name the end-effectors, so
that chains come in one order on every skeleton (SAN's reference code lists them by hand per
skeleton). The root's own rotation and movement stay those of the canonical motion: the file's
up axis, units and heading are a property of its coordinate frame, not of its topology.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import BvhClip
from robot_retarget.motion.canonicalize import clip_geometry
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.joint_map import JointMap, map_joints
from robot_retarget.motion.units import unit_scale_m
from robot_retarget.skeleton.armatures import (
    ArmatureTopology,
    canonical_topology,
    check_homeomorphic,
)
from robot_retarget.skeleton.canonical import Joint

# Canonical joints that may realise each end-effector, deepest first.
_END_JOINTS: tuple[tuple[Joint, ...], ...] = (
    (Joint.LeftToeBase, Joint.LeftFoot),
    (Joint.RightToeBase, Joint.RightFoot),
    (Joint.Head,),
    (Joint.LeftHand,),
    (Joint.RightHand,),
)


def end_effector_joints(joint_map: JointMap) -> tuple[int, ...]:
    """Source joints of the five end-effectors (armatures.END_EFFECTORS order): the deepest
    mapped joint of each (a toe where the skeleton has one, else the foot)."""
    out: list[int] = []
    for candidates in _END_JOINTS:
        found = [joint_map.source_joints[c] for c in candidates]
        out.append(next(j for j in found if j is not None))
    return tuple(out)


@dataclass(frozen=True)
class NativePose:
    """Armature rotations of a clip on its own skeleton.

    ``local_quats`` (T, A − 1, 4): the file's local rotation of each armature's far joint
    (armatures 1 … A − 1 of ``topology``; the root armature's data comes from the canonical
    motion), continuous in time; ``offsets`` (A − 1, 3) metres: the bone into each of them.
    """

    topology: ArmatureTopology
    local_quats: FloatArray = field(repr=False)
    offsets: FloatArray = field(repr=False)

    def __post_init__(self) -> None:
        a = self.topology.num_armatures - 1
        q = np.asarray(self.local_quats, dtype=np.float64)
        if q.ndim != 3 or q.shape[1:] != (a, 4):
            raise ValueError(f"local_quats must have shape (T, {a}, 4), got {q.shape}")
        if np.asarray(self.offsets).shape != (a, 3):
            raise ValueError(f"offsets must have shape ({a}, 3), got {np.shape(self.offsets)}")

    @property
    def num_frames(self) -> int:
        return int(self.local_quats.shape[0])

    def frames(self, start: int, stop: int) -> NativePose:
        return NativePose(self.topology, self.local_quats[start:stop], self.offsets)

    def resample(self, fps_in: float, fps_out: float) -> NativePose:
        """Slerp to ``fps_out`` over the same span, frame for frame as HumanMotion.resample."""
        t = self.num_frames
        count = math.floor((t - 1) / fps_in * fps_out + 1e-9) + 1
        x = np.arange(count) * (fps_in / fps_out)
        i0 = np.clip(np.floor(x).astype(np.int64), 0, t - 1)
        i1 = np.minimum(i0 + 1, t - 1)
        q = quat.slerp(self.local_quats[i0], self.local_quats[i1], (x - i0)[:, None])
        return NativePose(self.topology, q, self.offsets)


def native_pose(clip: BvhClip, motion: HumanMotion) -> NativePose:
    """``clip``'s armature rotations, frame for frame with ``motion`` = canonicalize(clip)
    (its dropped T-pose frames dropped, its unit, its frame count). Raises TopologyError when
    the skeleton does not pool to the canonical skeleton's primal skeleton (no shared latent
    space to read it into)."""
    jm = map_joints(clip.names, clip_geometry(clip), family=motion.name_family, path=clip.path)
    topology = ArmatureTopology.from_tree(
        f"{jm.family}-{clip.num_joints}j", clip.names, clip.parents, end_effector_joints(jm)
    )
    check_homeomorphic([canonical_topology(), topology])
    first = motion.tpose_frames_dropped
    body = clip.frames(first, first + motion.num_frames)
    joints = list(topology.joints[1:])
    local = quat.make_continuous(body.local_rotations()[:, joints], axis=0)
    offsets = np.asarray(clip.offsets[joints] * unit_scale_m(motion.unit), dtype=np.float64)
    return NativePose(topology, local, offsets)
