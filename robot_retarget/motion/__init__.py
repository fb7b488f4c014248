"""Motion I/O: BVH files, joint maps onto the canonical skeleton, HumanMotion, trajectories."""

from robot_retarget.motion.bvh import BvhClip, parse_bvh, read_bvh, write_bvh
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.motion.joint_map import FAMILIES, JointMap, map_joints

__all__ = [
    "FAMILIES",
    "BvhClip",
    "HumanMotion",
    "JointMap",
    "load_motion",
    "map_joints",
    "parse_bvh",
    "read_bvh",
    "write_bvh",
]
