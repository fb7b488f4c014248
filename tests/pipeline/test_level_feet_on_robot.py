"""OP3's soles in stance, as a tool that loads the trajectory sees them (real CMU walk).

The mocap rig's foot roll (about 20° outwards in stance on CMU 06) used to reach OP3's ankle
rolls: it stood on the outer edges of its soles. With ``retarget.level_feet`` (the default) the
soles lie within a few degrees of flat wherever the performer stands, and the manufacturer's
foot boxes (MuJoCo Menagerie's op3.xml) stay on the floor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import robot_retarget as rr
from robot_retarget.evaluation.robot.runner import with_retarget_overrides
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.pipeline.floating_base import human_foot_heights_m
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config

TIME_LIMIT_S = 240
FEET = ["l_ank_roll_link", "r_ank_roll_link"]
# op3.xml: two collision boxes per foot in the ankle roll link, bottoms 0.0305 m below it; the
# left foot's (centre x, y), (half x, y); the right foot's y mirrored.
_BOXES = (((0.024, 0.013), (0.0635, 0.028)), ((0.024, 0.0125), (0.057, 0.039)))
_LEFT = np.array(
    [
        [cx + sx * hx, cy + sy * hy, -0.0305]
        for (cx, cy), (hx, hy) in _BOXES
        for sx in (-1, 1)
        for sy in (-1, 1)
    ]
)
CORNERS = np.stack([_LEFT, _LEFT * [1.0, -1.0, 1.0]])  # (2, 8, 3)


def _stance_soles(config: RobotConfig, clip: Path) -> tuple[np.ndarray, np.ndarray]:
    """(tilt of each sole from flat, degrees; lowest foot-box corner, m), in frames where the
    performer's foot on that side is planted (either joint within 3 cm of its standing
    height)."""
    motion = load_motion(clip, max_frames=600)
    traj = rr.retarget(motion, config).trajectory
    assert traj.root_quat is not None
    assert traj.root_pos is not None
    kin = RobotKinematics(config)
    base = quat.to_matrix(traj.root_quat)
    rot = np.einsum("tij,tfjk->tfik", base, kin.frame_rotations(traj.q, FEET))
    pos = np.einsum("tij,tfj->tfi", base, kin.frame_positions(traj.q, FEET))
    corners = np.einsum("tfij,fcj->tfci", rot, CORNERS) + (pos + traj.root_pos[:, None])[:, :, None]
    tilt = np.degrees(np.arccos(np.clip(rot[..., 2, 2], -1.0, 1.0)))
    heights = human_foot_heights_m(motion.resample(traj.fps).positions()[: len(traj.q)])
    planted = np.stack([heights[:, [0, 2]].min(1), heights[:, [1, 3]].min(1)], 1) < 0.03
    return tilt[planted], corners[..., 2].min(-1)[planted]


@pytest.fixture(scope="module")
def walk(shared_data_dir: Path) -> Path:
    return shared_data_dir / "mocap" / "06" / "06_10.bvh"


def test_op3_stands_on_level_soles(walk: Path) -> None:
    tilt, lowest = _stance_soles(load_robot_config("op3"), walk)
    assert len(tilt) > 500
    assert np.median(tilt) < 8.0  # 4.7° (25.5° copying the rig's roll)
    assert (lowest < -0.01).mean() < 0.02  # 0.5 % of stance frames (71 %)


def test_copying_the_rigs_foot_roll_stood_op3_on_its_edges(walk: Path) -> None:
    config = with_retarget_overrides(load_robot_config("op3"), {"level_feet": 0.0})
    tilt, lowest = _stance_soles(config, walk)
    assert np.median(tilt) > 15.0
    assert (lowest < -0.015).mean() > 0.2
