"""The robot's floating base: where its base link is in the world, frame by frame.

Robotics tools place a robot by its base link's pose in a Z-up, x-forward, y-left world
(REP-103; URDF, MJCF, MuJoCo, Isaac and GMR's motion files use it), metres, quaternions w-x-y-z.
The performer's motion is Y-up, facing +Z, at human scale; this module turns it into that pose
for the robot's own proportions, with its feet on the ground:

- **orientation**: the trunk frame the joint angles were solved in (heading and lean of the
  performer's torso, :mod:`robot_retarget.skeleton.trunk`), applied to the robot's root frame
  through its config's up/forward axes: the limbs stand in the world where the performer's do;
- **horizontal path**: the pelvis' ground track from the first frame, scaled by the leg-length
  ratio (robot / performer: a 0.5 m robot takes proportionally shorter steps), plus a
  correction that pins a foot in stance where it landed (below);
- **height**: for each frame, the base height that puts the robot's lowest foot point (its
  config's foot frames, e.g. OP3's soles and toes) at the performer's foot height above their
  ground, scaled: z = 0 in stance; in a jump the robot leaves the ground as the performer did;
  no foot point ever goes below z = 0. The performer's foot height is that of whichever foot
  joint (ankle or toe) is nearest its own standing height: a heel strike (ankle down, toe up)
  and a toe-off (toe down, ankle up) both count as on the ground, as neither joint touches it.
- **foot pinning**: a foot the performer stands on that is on the ground (within ``contact_m``
  of z = 0) in two consecutive frames must not slide: the base moves by the mean slip of such
  feet. Scaled human strides and
  the robot's own leg kinematics never match exactly; this keeps a foot in stance planted, at
  the price of a base path that differs from the scaled human one by what the robot's legs
  really cover (a robot whose retargeted steps barely lift its feet shuffles: it travels less).

Origin: the world origin is the ground point under the performer's pelvis at the first frame;
the robot faces +x when the performer faces their own +Z (canonical forward).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ConfigError, RetargetError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.optimize.bone_model import body_to_root, foot_frames
from robot_retarget.robot.canonical_skeleton import (
    robot_canonical_skeleton,
)
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import Joint
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.skeleton.trunk import trunk_frames_of_positions

# Canonical human axes (X left, Y up, Z forward) → world (x forward, y left, z up).
HUMAN_TO_WORLD = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
CONTACT_M = 0.01  # a foot point this close to the ground counts as standing on it
# Ankles, then toes, left before right: a joint's standing height is pooled over both sides.
_FOOT_JOINTS = (Joint.LeftFoot, Joint.RightFoot, Joint.LeftToeBase, Joint.RightToeBase)
HUMAN_CONTACT_M = 0.05  # a performer's foot joint this near its standing height may be planted…
HUMAN_CONTACT_SPEED_M_S = 0.6  # …when it also moves slower than this (horizontal)
_SIDE_COLUMNS = {"Left": (0, 2), "Right": (1, 3)}  # columns of _FOOT_JOINTS per side
# A joint's standing height: a low percentile of its height over the clip (robust to glitches,
# and to a clip spent on one leg: both sides are pooled).
_GROUND_PERCENTILE = 2.0


class FloatingBaseError(RetargetError, ValueError):
    """Joint angles and the motion they were retargeted from do not fit together; ``expected``
    and ``got`` are the shapes."""

    def __init__(self, message: str, *, expected: tuple[int, ...], got: tuple[int, ...]) -> None:
        self.expected = expected
        self.got = got
        super().__init__(message)


@dataclass(frozen=True)
class FloatingBase:
    """Base link pose per frame: ``root_pos`` (T, 3) m and ``root_quat`` (T, 4) w-x-y-z in the
    world; ``feet`` (T, F, 3) the robot's foot points in the world (for checks and metrics)."""

    root_pos: FloatArray
    root_quat: FloatArray
    feet: FloatArray
    foot_frames: tuple[str, ...]


def foot_points(config: RobotConfig) -> tuple[str, ...]:
    """The robot frames that touch the ground: every fixed frame on the links that carry its
    mapped feet (OP3: sole centre and toe of each ankle-roll link)."""
    ends = foot_frames(config)
    if not ends:
        raise ConfigError(
            f"robot {config.name} maps no foot bones, so it has no point to stand on",
            path=config.source_path,
            key="bones",
            allowed="bones ending at LeftToeBase/RightToeBase or LeftFoot/RightFoot",
        )
    parents = {f.name: f.parent_link for f in config.frames}
    links = {parents.get(e) for e in ends}
    return tuple(f.name for f in config.frames if f.parent_link in links) or ends


def leg_length_m(skeleton: Skeleton) -> float:
    """Hip → knee → ankle length of the canonical skeleton's left leg (metres)."""
    off = skeleton.offsets
    return float(np.linalg.norm(off[Joint.LeftLeg]) + np.linalg.norm(off[Joint.LeftFoot]))


def leg_length_ratio(config: RobotConfig, skeleton: Skeleton) -> float:
    """The robot's leg length over the performer's (``skeleton``'s): what scales the
    performer's path and foot heights to the robot."""
    return leg_length_m(robot_canonical_skeleton(config)) / leg_length_m(skeleton)


def floating_base(
    config: RobotConfig,
    motion: HumanMotion,
    q: npt.ArrayLike,
    *,
    contact_m: float = CONTACT_M,
    pin_feet: bool = True,
    trunk_frames: npt.ArrayLike | None = None,
) -> FloatingBase:
    """The base link's world pose for joint angles ``q`` (T, J) retargeted from ``motion`` (T
    frames at the same rate).

    ``trunk_frames`` (T, 3, 3): the trunk frames (columns forward, left, up, canonical axes;
    :mod:`robot_retarget.skeleton.trunk`) the joint angles were solved in — the retargeted
    pose's, as ``convert`` passes them — default the performer's own. The base turns and tilts
    with them, so the limbs stand in the world as the optimizer placed them."""
    q_arr = np.asarray(q, dtype=np.float64)
    n = motion.num_frames
    if q_arr.shape != (n, config.num_joints):
        raise FloatingBaseError(
            f"q must be ({n}, {config.num_joints}) (one row per motion frame, robot joint "
            f"order), got {q_arr.shape}; resample the motion to the trajectory's rate first",
            expected=(n, config.num_joints),
            got=q_arr.shape,
        )
    feet = foot_points(config)
    ratio = leg_length_ratio(config, motion.skeleton)

    # Orientation: root frame → body axes (forward, left, up) → trunk frame → world.
    human = motion.positions()
    frames = np.asarray(
        trunk_frames_of_positions(human) if trunk_frames is None else trunk_frames,
        dtype=np.float64,
    )
    if frames.shape != (n, 3, 3) or not np.all(np.isfinite(frames)):
        raise FloatingBaseError(
            f"trunk_frames must be ({n}, 3, 3) finite rotations (one per motion frame), got "
            f"{frames.shape}",
            expected=(n, 3, 3),
            got=frames.shape,
        )
    base_rot = base_rotations(config, frames)

    # Height targets: the performer's foot height above their ground, scaled.
    heights = human_foot_heights_m(human)  # (T, 4)
    lowest = ratio * heights.min(axis=1)
    track = (human[:, 0] - human[:1, 0]) @ HUMAN_TO_WORLD.T * ratio  # (T, 3) world

    local_feet = RobotKinematics(config).frame_positions(q_arr, list(feet))  # (T, F, 3) root
    rel = np.einsum("tij,tfj->tfi", base_rot, local_feet)  # feet relative to the base, world
    z = lowest - rel[:, :, 2].min(axis=1)
    pos = np.column_stack([track[:, 0], track[:, 1], z])
    if pin_feet:
        _pin_stance_feet(pos, rel, planted_feet(config, human, motion.fps), contact_m)
    world_feet = rel + pos[:, None, :]
    root_quat = quat.make_continuous(quat.from_matrix(base_rot), axis=0)
    return FloatingBase(pos, root_quat, world_feet, feet)


def base_rotations(config: RobotConfig, trunk_frames: npt.ArrayLike) -> FloatArray:
    """(T, 3, 3) the base link's orientation in the world (root-frame vectors → world) for
    trunk frames (T, 3, 3): root axes → body axes (forward, left, up) → trunk frame → world."""
    frames = np.asarray(trunk_frames, dtype=np.float64)
    return np.asarray(HUMAN_TO_WORLD @ frames @ body_to_root(config).T, dtype=np.float64)


def _frame_sides(config: RobotConfig, frames: tuple[str, ...]) -> list[str]:
    """Left or Right for each foot point: the side of the mapped foot bone ending on its link."""
    link = {f.name: f.parent_link for f in config.frames}
    side = {link.get(b.end_frame): b.canonical_end for b in config.bones}
    return ["Left" if side.get(link.get(f), "").startswith("Left") else "Right" for f in frames]


def human_foot_heights_m(positions: npt.ArrayLike) -> FloatArray:
    """(T, 4) height of each of the performer's foot joints (ankles, then toes; left, right)
    above its own standing height, ≥ 0, from global joint positions (T, 22, 3) Y up, metres.

    Each joint is measured from its own standing height (ankles stand higher than toes): the
    foot is on the ground when either is there, whichever part of the sole carries it."""
    y = np.asarray(positions, dtype=np.float64)[:, list(_FOOT_JOINTS), 1]
    ankle = float(np.percentile(y[:, :2], _GROUND_PERCENTILE))
    toe = float(np.percentile(y[:, 2:], _GROUND_PERCENTILE))
    return np.maximum(y - np.array([ankle, ankle, toe, toe]), 0.0)


def performer_foot_heights_m(config: RobotConfig, motion: HumanMotion) -> dict[str, FloatArray]:
    """Per side ("Left", "Right"), (T,) how high the performer's foot is above their ground,
    scaled to the robot: the lower of its ankle and toe above their standing heights (the
    rule that places the base, :func:`floating_base`), times the leg-length ratio."""
    ratio = leg_length_ratio(config, motion.skeleton)
    heights = human_foot_heights_m(motion.positions())
    return {
        side: ratio * heights[:, list(cols)].min(axis=1) for side, cols in _SIDE_COLUMNS.items()
    }


def foot_sides(config: RobotConfig) -> dict[str, tuple[str, ...]]:
    """The robot's foot points (:func:`foot_points`) per side ("Left", "Right")."""
    points = foot_points(config)
    sides = _frame_sides(config, points)
    return {
        side: tuple(p for p, s in zip(points, sides, strict=True) if s == side)
        for side in ("Left", "Right")
        if side in sides
    }


def _human_planted(
    human: FloatArray, heights: FloatArray, fps: float, sides: list[str]
) -> npt.NDArray[np.bool_]:
    """(T, F): the performer's foot on each robot foot frame's side is planted: one of its
    joints near its standing height and slow."""
    horizontal = human[:, list(_FOOT_JOINTS)][:, :, [0, 2]]  # (T, 4, 2)
    vel = np.gradient(horizontal, axis=0) * fps if len(human) > 1 else 0.0 * horizontal
    joint_planted = (heights <= HUMAN_CONTACT_M) & (
        np.linalg.norm(vel, axis=-1) <= HUMAN_CONTACT_SPEED_M_S
    )
    out = np.zeros((len(human), len(sides)), dtype=bool)
    for k, side in enumerate(sides):
        out[:, k] = joint_planted[:, list(_SIDE_COLUMNS[side])].any(axis=1)
    return out


def _pin_stance_feet(
    pos: FloatArray, rel: FloatArray, planted: npt.NDArray[np.bool_], contact_m: float
) -> None:
    """Shift the base horizontally (in place) so feet on the ground in consecutive frames do
    not slide; the shift accumulates (the robot covers the ground its own legs cover).

    Only feet the performer stands on (``planted``) are held. A robot foot near the floor that
    the performer has lifted is swinging: OP3's crouched gait carries it forward within
    ``contact_m`` of the floor, and holding it as well (as this did when no planted foot was
    down) moved the base backwards for a few frames at every step — 0.32 m back for 0.76 m
    forward on CMU 02_01, up to 1.3 m/s — where the performer walks steadily on."""
    offset = np.zeros(2)
    prev_xy: FloatArray | None = None
    prev_down: npt.NDArray[np.bool_] | None = None
    for t in range(len(pos)):
        pos[t, :2] += offset
        xy = rel[t, :, :2] + pos[t, :2]
        # Only a foot the performer stands on: OP3's swing foot skims the floor within
        # contact_m, and pinning it pushed the base backwards at every step (below).
        down = (rel[t, :, 2] + pos[t, 2] <= contact_m) & planted[t]
        if prev_xy is not None and prev_down is not None:
            stance = down & prev_down
            if stance.any():
                slip = (prev_xy[stance] - xy[stance]).mean(axis=0)
                offset += slip
                pos[t, :2] += slip
                xy = xy + slip
        prev_xy, prev_down = xy, down


def trajectory_feet(
    config: RobotConfig, q: npt.ArrayLike, root_pos: npt.ArrayLike, root_quat: npt.ArrayLike
) -> FloatArray:
    """(T, F, 3) the robot's foot points (:func:`foot_points`) in the world for joint angles
    ``q`` (T, J) on a base at ``root_pos`` (T, 3) / ``root_quat`` (T, 4) w-x-y-z: where a tool
    that loads the trajectory puts its feet."""
    local = RobotKinematics(config).frame_positions(q, list(foot_points(config)))
    rot = quat.to_matrix(np.asarray(root_quat, dtype=np.float64))
    rel = np.einsum("tij,tfj->tfi", rot, local)
    return np.asarray(rel + np.asarray(root_pos, dtype=np.float64)[:, None, :])


def planted_feet(
    config: RobotConfig, positions: npt.ArrayLike, fps: float
) -> npt.NDArray[np.bool_]:
    """(T, F): the performer, at global joint positions (T, 22, 3) Y up at ``fps``, stands on
    the side of each of the robot's foot points (:func:`foot_points`): a foot joint near its
    standing height and slow. The pinning holds only these feet; eval-robot's skate under
    planted feet counts only them."""
    human = np.asarray(positions, dtype=np.float64)
    sides = _frame_sides(config, foot_points(config))
    return _human_planted(human, human_foot_heights_m(human), fps, sides)


def foot_skate_m_s(feet: npt.ArrayLike, fps: float, contact_m: float = CONTACT_M) -> float:
    """Mean horizontal speed (m/s) of robot foot points that stay on the ground (z within
    ``contact_m``) from one frame to the next; 0 when no foot is ever down twice in a row."""
    f = np.asarray(feet, dtype=np.float64)  # (T, F, 3) world
    skate = _sliding(f, fps, f[:, :, 2] <= contact_m)
    return 0.0 if skate is None else skate


def planted_skate_m_s(
    feet: npt.ArrayLike, fps: float, planted: npt.ArrayLike, contact_m: float = CONTACT_M
) -> float | None:
    """:func:`foot_skate_m_s` of the points whose side the performer stands on in both frames
    (``planted`` (T, F), :func:`planted_feet`): a stance foot sliding, not a swing foot
    skimming the floor. None when no such point is on the ground twice in a row (nothing
    to measure, not a perfect score)."""
    f = np.asarray(feet, dtype=np.float64)
    return _sliding(f, fps, (f[:, :, 2] <= contact_m) & np.asarray(planted, dtype=bool))


def swing_scuff_share(
    config: RobotConfig, feet: npt.ArrayLike, planted: npt.ArrayLike, contact_m: float = CONTACT_M
) -> float | None:
    """The share of single-support swing frames (the performer has lifted a foot and stands
    on the other) in which the robot's foot on the lifted side is within ``contact_m`` of the
    floor: a swing foot that would scrape. ``feet`` (T, F, 3) world and ``planted`` (T, F)
    (:func:`planted_feet`) in :func:`foot_points` order; None when the performer never stands
    on one foot."""
    scrapes, swings = swing_scuffs(config, feet, planted, contact_m)
    return scrapes / swings if swings else None


def swing_scuffs(
    config: RobotConfig, feet: npt.ArrayLike, planted: npt.ArrayLike, contact_m: float = CONTACT_M
) -> tuple[int, int]:
    """(scraping, all) single-support swing frames, per foot (:func:`swing_scuff_share`)."""
    f = np.asarray(feet, dtype=np.float64)
    down = np.asarray(planted, dtype=bool)
    sides = _frame_sides(config, foot_points(config))
    scrapes, swings = 0, 0
    for side in set(sides):
        own = [k for k, s in enumerate(sides) if s == side]
        other = [k for k, s in enumerate(sides) if s != side]
        if not other:
            continue
        swing = ~down[:, own].any(axis=1) & down[:, other].any(axis=1)
        swings += int(swing.sum())
        scrapes += int((f[swing][:, own, 2].min(axis=1) <= contact_m).sum())
    return scrapes, swings


def _sliding(feet: FloatArray, fps: float, down: npt.NDArray[np.bool_]) -> float | None:
    """Mean horizontal speed of the points ``down`` in two consecutive frames (None: none)."""
    if len(feet) < 2:
        return None
    both = down[1:] & down[:-1]
    if not both.any():
        return None
    step = np.linalg.norm(feet[1:, :, :2] - feet[:-1, :, :2], axis=-1)
    return float(step[both].mean() * fps)
