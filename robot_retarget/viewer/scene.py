"""What the viewer draws, as plain arrays in the robot world (Z up, x forward, metres).

The robot is its config's kinematic tree drawn as segments between frame origins — the links'
joint origins and the fixed frames (hands, soles) — computed by the project's own forward
kinematics (:class:`robot_retarget.robot.kinematics.RobotKinematics`) at the trajectory's
floating-base pose. The performer is the canonical 22-joint skeleton, turned from its Y-up
axes into the robot world, scaled to the robot's leg length and set beside the robot so both
can be compared at one size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint

# The performer's foot joints: their low percentile over the clip is the performer's ground.
_FOOT_JOINTS = (Joint.LeftFoot, Joint.RightFoot, Joint.LeftToeBase, Joint.RightToeBase)
_GROUND_PERCENTILE = 2.0


class RobotFigure:
    """The robot as line segments: one per link (parent origin → child origin) and one per
    fixed frame (its link's origin → the frame)."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        self.kinematics = RobotKinematics(config)
        chain = self.kinematics.chain
        n_links = len(chain.link_names)
        edges = [(int(p), k + 1) for k, p in enumerate(chain.link_parent)]
        edges += [(int(p), n_links + f) for f, p in enumerate(chain.frame_parent)]
        self.edges = np.array(edges, dtype=np.int64).reshape(-1, 2)

    def points(
        self,
        q: npt.ArrayLike,
        root_pos: npt.ArrayLike | None = None,
        root_quat: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Frame origins (…, F, 3) in the world for joint angles (…, J) and the base pose
        (root_pos (…, 3) m, root_quat (…, 4) w-x-y-z); no pose: the base at the origin."""
        q_arr = np.asarray(q, dtype=np.float64)
        lead = q_arr.shape[:-1]
        root = np.broadcast_to(np.eye(4), (*lead, 4, 4)).copy()
        if root_quat is not None:
            root[..., :3, :3] = quat.to_matrix(quat.normalize(root_quat))
        if root_pos is not None:
            root[..., :3, 3] = np.asarray(root_pos, dtype=np.float64)
        return self.kinematics.frame_positions(q_arr, root_transform=root)

    def segments(
        self,
        q: npt.ArrayLike,
        root_pos: npt.ArrayLike | None = None,
        root_quat: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Segments (…, E, 2, 3) in the world; see :meth:`points`."""
        return self.points(q, root_pos, root_quat)[..., self.edges, :]

    def height_m(self) -> float:
        """The standing robot's height (init pose, top to bottom frame), metres."""
        pts = self.points(self.config.init_pose)
        up = np.asarray(self.config.up_axis, dtype=np.float64)
        heights = pts @ up
        return float(heights.max() - heights.min())


HUMAN_EDGES: IntArray = np.array(
    [(p, j) for j, p in enumerate(CANONICAL_PARENTS) if p >= 0], dtype=np.int64
)


@dataclass(frozen=True)
class PerformerFigure:
    """The performer's joints (T, 22, 3) in the robot world at ``fps``, scaled by ``scale``
    (robot leg / performer leg), feet on z = 0, first pelvis ground point at ``offset``."""

    points: FloatArray
    fps: float
    scale: float

    @property
    def num_frames(self) -> int:
        return int(self.points.shape[0])

    def segments(self, frame: int) -> FloatArray:
        """Segments (E, 2, 3) of one frame (clamped to the clip)."""
        k = min(max(frame, 0), self.num_frames - 1)
        return self.points[k][HUMAN_EDGES]

    def frame_at(self, time_s: float) -> int:
        """The clip frame shown at trajectory time ``time_s`` (the clip starts at t = 0)."""
        return min(max(round(time_s * self.fps), 0), self.num_frames - 1)


def performer_figure(
    motion: HumanMotion, config: RobotConfig, offset: npt.ArrayLike = (0.0, 0.0, 0.0)
) -> PerformerFigure:
    """The performer of ``motion`` in ``config``'s world, at the robot's size, beside it."""
    # floating_base holds the frame conventions convert used; imported here because it pulls in
    # the optimizer's modules, which a trajectory-only view does not need.
    from robot_retarget.pipeline.floating_base import HUMAN_TO_WORLD, leg_length_ratio

    scale = leg_length_ratio(config, motion.skeleton)
    human = motion.positions()
    world = (human - human[:1, :1] * np.array([1.0, 0.0, 1.0])) @ HUMAN_TO_WORLD.T * scale
    ground = float(np.percentile(world[:, list(_FOOT_JOINTS), 2], _GROUND_PERCENTILE))
    world = world - np.array([0.0, 0.0, ground]) + np.asarray(offset, dtype=np.float64)
    return PerformerFigure(points=world, fps=float(motion.fps), scale=float(scale))
