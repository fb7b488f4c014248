"""``inspect`` of a robot's own BVH (``convert --bvh-out``, for Blender): which robot, how long,
and where its base goes — instead of the human-skeleton mapping error such a file gets.

A BVH is a robot's when its joints are exactly one bundled robot's links (``--robot`` names
the one to compare with). Its root channels are the base link's position in BVH axes (Y up):
the robot's Z-up world's z is BVH Y, its x and y are BVH Z and X
(:mod:`robot_retarget.pipeline.robot_bvh`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from robot_retarget.motion.bvh import BvhClip
from robot_retarget.robot.config import RobotConfig


def robot_links(config: RobotConfig) -> set[str]:
    """The link names a robot BVH of ``config`` has as its joints."""
    return {config.root_link, *(j.child_link for j in config.joints)}


def robot_of_bvh(clip: BvhClip, robot: str | None = None) -> RobotConfig | None:
    """The robot whose links are exactly ``clip``'s joints: ``robot`` if given and it fits,
    else the one bundled robot that does; None if none does."""
    from robot_retarget.robot.loader import available_robots

    names = set(clip.names)
    for name in [robot] if robot is not None else available_robots():
        config, links = _robot_and_links(name)
        if links == names:
            return config
    return None


@functools.cache
def _robot_and_links(name: str) -> tuple[RobotConfig, frozenset[str]]:
    """A robot config and its links, loaded once per process: ``inspect`` of a folder asks for
    every clip (20 ms per clip for the two bundled robots, loaded each time)."""
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config(name)
    return config, frozenset(robot_links(config))


def describe_robot_bvh(path: str, clip: BvhClip, config: RobotConfig) -> dict[str, Any]:
    """Facts about a robot BVH, as JSON-ready values (lengths in metres, as it is written)."""
    root = clip.motion[:, clip.channel_start[0] : clip.channel_start[0] + 3]
    pos = {axis[0]: root[:, k] for k, axis in enumerate(clip.channels[0][:3])}
    height = pos["Y"]
    ground = np.stack([pos["Z"], pos["X"]], axis=1)  # world x, y
    frames = clip.num_frames
    return {
        "file": path,
        "kind": "robot BVH",
        "robot": config.name,
        "links": len(clip.names),
        "frames": frames,
        "fps": 1.0 / clip.frame_time_s,
        "duration_s": frames * clip.frame_time_s,
        "base_height_m": [float(height.min()), float(height.max())],
        "base_path_m": float(np.linalg.norm(np.diff(ground, axis=0), axis=1).sum()),
    }


def format_robot_bvh_text(info: dict[str, Any]) -> str:
    return "\n".join(
        [
            f"{info['file']}",
            f"  kind:        robot BVH ({info['robot']}'s {info['links']} links as joints, "
            "as convert --bvh-out writes it for Blender)",
            f"  frames:      {info['frames']} at {info['fps']:.6g} fps "
            f"({info['duration_s']:.3f} s)",
            f"  base:        height {info['base_height_m'][0]:.3f}–"
            f"{info['base_height_m'][1]:.3f} m, path {info['base_path_m']:.2f} m",
            "  joint angles: in the trajectory file convert wrote with it (inspect that one "
            "for limits and feet)",
        ]
    )
