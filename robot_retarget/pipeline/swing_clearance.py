"""Swing feet lifted off the floor: each foot at least as high as the performer's, scaled.

A robot foot copies the performer's foot *angle*, and small humanoids have long feet: OP3's
ankle-to-toe is 0.29 of its leg, a person's 0.16. Where a performer swings a foot pitched
toe-down (the CMU ankle-to-toe line 41–53° below level in swing) the robot's lowest foot point
hangs 6.1–6.8 cm below its ankle (3.1 cm with the sole flat), and on CMU walks OP3's swing
foot skimmed the floor (lowest point 0.4–1.1 cm at the median per foot, under 1 cm in 42–94 %
of the single-support swing frames of 02_01, 06_01, 08_01) while its ankle rose as high as the
performer's, scaled (3.2–3.8 cm against 1.4–3.1 cm): the legs are right; the foot's angle is
what scrapes. (Weighting the foot's direction more, or damping the ankles less, in the solve
cost shin error or jerk: README, "Swing feet".)

So after the whole clip is solved and the floating base placed, each foot the performer has
lifted whose lowest point is below the performer's same-side foot height (the floating base's
own height rule, per side: the lower of ankle and toe above their standing heights, scaled by
the leg-length ratio) is turned about its ankle's pitch joint by the smallest angle that lifts
it there, or as far as a turn can (a flat foot under a low ankle). Only that joint moves, so
every scored segment keeps its direction. The turns are smoothed over ``SMOOTH_S`` and held
where needed, reached and left within the joint's velocity limit (a foot the performer stands
on is not turned, but in the first and last ``STANCE_RAMP_S`` of its stance, heel strike and
heel-off, where it is lifted to the performer's height there as well), at most
``MAX_TURN_RAD`` from the solved angle
and inside the joint's limits; then the base is placed again, and the feet lifted again from
there (``PASSES``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.optimize.bone_model import body_to_root
from robot_retarget.pipeline.floating_base import (
    FloatingBase,
    floating_base,
    foot_points,
    foot_sides,
    performer_foot_heights_m,
    planted_feet,
)
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics, homogeneous

SMOOTH_S = 0.04  # Gaussian σ of the turns (5 frames at 125 Hz): no step where a lift starts
MAX_TURN_RAD = 0.8  # the largest turn of a foot from its solved angle, either way (46°)
# The first and last STANCE_RAMP_S of a stance (heel strike and heel-off) are lifted as a
# swing is (to the performer's height there, near the floor) and the turns ramp there; deeper
# in a stance nothing is turned. Chosen on the tuning subjects 02 05 13 (OP3, share of swing frames
# within 1 cm of the floor / jerk): none 0.158 / 1677 rad/s³, 0.05 s 0.142 / 1545, 0.1 s
# 0.141 / 1520, 0.2 s 0.142 / 1478, anywhere 0.159 / 1427 (unlifted 0.352 / 1370); 0.2 s
# and more tipped the planted foot longer for little less jerk (an unbounded ramp had put
# 08_01's left foot on its toes, 46°, for 24 frames of stance).
STANCE_RAMP_S = 0.1
PASSES = 3  # lift, place the base again, lift from there: at most this many times
_STEPS = 41  # turns tried in [−MAX_TURN_RAD, MAX_TURN_RAD]: 2.3° apart


@dataclass(frozen=True)
class FootPitch:
    """One foot: its pitch joint (index) and the foot points it carries (frame names)."""

    joint: int
    points: tuple[str, ...]


def foot_pitch_joints(
    config: RobotConfig, sides: dict[str, tuple[str, ...]], ankles: dict[str, str]
) -> dict[str, FootPitch]:
    """Per side, the joint that turns the foot points ``sides[side]`` about a lateral axis
    without moving the ankle frame ``ankles[side]`` (the foot bone's start): of the joints that
    move only the foot and whose axis at the zero pose is within 60° of the robot's left, the
    one that moves most of its points, then most of the robot's frames (an ankle, not a toe
    joint below it), then the most lateral."""
    kin = RobotKinematics(config)
    left = body_to_root(config)[:, 1]  # the robot's left, root frame
    moves = kin.carried_frames()  # (J, every frame)
    carried = moves.sum(axis=1)  # (J,)
    rot = kin.frame_rotations(np.zeros(config.num_joints), [c.child_link for c in config.joints])
    out: dict[str, FootPitch] = {}
    for side, points in sides.items():
        moved = moves[:, kin.frame_indices([*points, ankles[side]])]  # (J, P + 1)
        # Of the joints with an axis within 60° of lateral: the one that turns most foot
        # points, then most of the robot's frames (an ankle before a toe joint below it),
        # then the most lateral.
        best, best_key = -1, (0, 0, 0.0)
        for j, joint in enumerate(config.joints):
            if moved[j, -1] or not moved[j, :-1].any():
                continue  # moves the ankle (a leg joint), or not the foot
            align = abs(float(left @ rot[j] @ np.asarray(joint.axis, dtype=np.float64)))
            key = (int(moved[j, :-1].sum()), int(carried[j]), align)
            if align > 0.5 and key > best_key:
                best, best_key = j, key
        if best >= 0:
            out[side] = FootPitch(best, tuple(points))
    return out


def base_transforms(root_pos: npt.ArrayLike, root_quat: npt.ArrayLike) -> FloatArray:
    """(T, 4, 4) the base link's pose in the world from positions (T, 3) and w-x-y-z (T, 4)."""
    rot = quat.to_matrix(np.asarray(root_quat, dtype=np.float64))
    return homogeneous(rot, np.asarray(root_pos, dtype=np.float64))


def lift_turns(
    kin: RobotKinematics,
    q: FloatArray,
    base: FloatArray,
    foot: FootPitch,
    axis_local: FloatArray,
    child_link: str,
    wanted_m: FloatArray,
    lower: float,
    upper: float,
) -> FloatArray:
    """(T,) per frame the turn of ``foot.joint`` (rad) that lifts the foot's lowest point to
    ``wanted_m`` (T,) above the floor: the smallest that does, else the one that lifts it
    most; 0 where it is high enough already. ``axis_local``: the joint's axis in its child
    link ``child_link``, whose origin is on the axis."""
    turns = np.zeros(len(q))
    rot, pos = kin.frame_poses(q, [child_link, *foot.points], base)
    low = pos[:, 1:, 2].min(axis=-1)
    need = np.flatnonzero(low < wanted_m)
    if need.size == 0:
        return turns
    tried = np.linspace(-MAX_TURN_RAD, MAX_TURN_RAD, _STEPS)
    j = foot.joint
    actual = np.clip(q[need, j, None] + tried, lower, upper) - q[need, j, None]  # (N, K)
    axis = rot[need, 0] @ axis_local  # (N, 3) world
    origin = pos[need, 0]
    turns_about = quat.from_axis_angle(axis[:, None, :], actual)[:, :, None, :]  # (N, K, 1, 4)
    turned = quat.rotate(turns_about, (pos[need, 1:] - origin[:, None])[:, None])  # (N, K, P, 3)
    heights = turned[..., 2].min(axis=-1) + origin[:, None, 2]  # (N, K)
    enough = heights >= wanted_m[need, None]
    # The smallest turn that is enough; where none is, the one that lifts most.
    size = np.where(enough, np.abs(actual), np.inf)
    pick = np.where(enough.any(axis=1), size.argmin(axis=1), heights.argmax(axis=1))
    rows = np.arange(len(need))
    turns[need] = actual[rows, pick]
    # A turn that does not lift the foot is none (the foot is as high as it gets).
    turns[need[heights[rows, pick] <= low[need]]] = 0.0
    return turns


def smooth(turns: FloatArray, fps: float, sigma_s: float = SMOOTH_S) -> FloatArray:
    """``turns`` (T,) under a Gaussian of σ ``sigma_s`` (edges held)."""
    sigma = sigma_s * fps
    if sigma < 0.5 or len(turns) < 2:
        return turns.copy()
    half = int(np.ceil(3.0 * sigma))
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    k /= k.sum()
    padded = np.concatenate([np.full(half, turns[0]), turns, np.full(half, turns[-1])])
    return np.asarray(np.convolve(padded, k, mode="valid"), dtype=np.float64)


def _cone(values: FloatArray, mask: npt.NDArray[np.bool_], slope: float, sign: float) -> FloatArray:
    """The least function (``sign`` 1; the greatest for -1) that is at least (at most)
    ``values`` where ``mask`` and changes by at most ``slope`` a frame: ``values[s] - slope·|t -
    s|`` maximised over the masked frames s (-inf / +inf where there are none)."""
    out = [sign * float(v) if m else -np.inf for v, m in zip(values, mask, strict=True)]
    for t in range(1, len(out)):
        out[t] = max(out[t], out[t - 1] - slope)
    for t in range(len(out) - 2, -1, -1):
        out[t] = max(out[t], out[t + 1] - slope)
    return sign * np.array(out, dtype=np.float64)


def held_turns(
    column: FloatArray,
    turns: FloatArray,
    step: float,
    kept: npt.NDArray[np.bool_] | None = None,
) -> FloatArray:
    """``column`` (T,) turned by ``turns`` (T,) where they are not 0, and no further than it
    must be elsewhere to get there and back within ``step`` a frame: at least ``column +
    turns`` where a turn is positive, at most where negative, ``column`` itself where neither
    needs it, and exactly ``column`` in the ``kept`` frames (a foot the performer stands on:
    a turn there would tip it onto its toes or heel), which win where the two meet. Each frame
    changes by at most ``step`` or by what ``column`` itself changes there, whichever is more
    (max, min and clip of such functions)."""
    target = column + turns
    up = _cone(target, turns > 0.0, step, 1.0)
    down = _cone(target, turns < 0.0, step, -1.0)
    out = np.minimum(np.maximum(column, up), down)
    if kept is not None and kept.any():
        below = _cone(column, kept, step, 1.0)  # the lowest a frame may be and reach them
        above = _cone(column, kept, step, -1.0)
        out = np.minimum(np.maximum(out, below), above)
    return np.asarray(out, dtype=np.float64)


def lift_swing_feet(
    config: RobotConfig,
    q: npt.ArrayLike,
    root_pos: npt.ArrayLike,
    root_quat: npt.ArrayLike,
    wanted_m: dict[str, FloatArray],
    feet: dict[str, FootPitch],
    fps: float,
    *,
    solved: npt.ArrayLike | None = None,
    planted: dict[str, npt.NDArray[np.bool_]] | None = None,
) -> FloatArray:
    """Joint angles (T, J) with each foot in ``feet`` turned about its pitch joint so that its
    lowest point is at least ``wanted_m[side]`` (T,) above the floor (module docstring), inside
    the joint's limits, at most ``MAX_TURN_RAD`` from ``solved`` (the angles as solved, before
    any lift; default ``q``), and no faster than its velocity limit at ``fps`` where ``q`` was
    not; unturned in the frames ``planted[side]`` (T,). The base (``root_pos``, ``root_quat``)
    is the one the feet were measured on; place it again afterwards."""
    out = np.array(q, dtype=np.float64)
    if len(out) == 0:
        return out
    start = out.copy() if solved is None else np.asarray(solved, dtype=np.float64)
    kin = RobotKinematics(config)
    base = base_transforms(root_pos, root_quat)
    step = np.asarray(config.max_velocity, dtype=np.float64) / fps
    lower = np.asarray(config.lower, dtype=np.float64)
    upper = np.asarray(config.upper, dtype=np.float64)
    for side, foot in feet.items():
        j = foot.joint
        joint = config.joints[j]
        axis = np.asarray(joint.axis, dtype=np.float64)
        axis = axis / np.linalg.norm(axis)
        turns = lift_turns(
            kin, out, base, foot, axis, joint.child_link, wanted_m[side], lower[j], upper[j]
        )
        if not turns.any():
            continue
        kept = None if planted is None else planted.get(side)
        column = held_turns(out[:, j], smooth(turns, fps), float(step[j]), kept)
        # Clamps to bands that are themselves within the speed limit keep it there.
        column = np.clip(column, start[:, j] - MAX_TURN_RAD, start[:, j] + MAX_TURN_RAD)
        out[:, j] = np.clip(column, lower[j], upper[j])
    return out


def robot_foot_pitches(config: RobotConfig) -> dict[str, FootPitch]:
    """Per side, the robot's foot pitch joint and foot points (empty: the robot maps no foot
    bone with an ankle frame, or has no such joint)."""
    ankles = {
        b.canonical.removesuffix("Foot"): b.start_frame
        for b in config.bones
        if b.canonical in ("LeftFoot", "RightFoot")
    }
    sides = {s: p for s, p in foot_sides(config).items() if s in ankles}
    return foot_pitch_joints(config, sides, ankles) if sides else {}


def _deep_in(mask: npt.NDArray[np.bool_], frames: float) -> npt.NDArray[np.bool_]:
    """``mask`` without its frames within ``frames`` of an unmasked one."""
    if frames <= 0.0 or mask.all():
        return mask.copy()
    gap = -_cone(np.zeros(len(mask)), ~mask, 1.0, 1.0)  # frames to the nearest unmasked one
    return np.asarray(mask & (gap > frames), dtype=bool)


def clear_swing_feet(
    config: RobotConfig,
    motion: HumanMotion,
    q: npt.ArrayLike,
    *,
    trunk_frames: npt.ArrayLike | None = None,
) -> tuple[FloatArray, FloatingBase]:
    """Joint angles (T, J) retargeted from ``motion`` (T frames at the same rate) with the swing
    feet lifted (module docstring), and the floating base placed for them."""
    base = floating_base(config, motion, q, trunk_frames=trunk_frames)
    feet = robot_foot_pitches(config)
    if not feet:
        return np.array(q, dtype=np.float64), base
    # Only a foot the performer has lifted, or at the ends of its stance: deeper in, one they
    # stand on is the base's (its pinning).
    heights = performer_foot_heights_m(config, motion)
    planted = planted_feet(config, motion.positions(), motion.fps)
    columns = foot_points(config)  # planted's columns
    standing = {
        side: _deep_in(planted[:, columns.index(foot.points[0])], STANCE_RAMP_S * motion.fps)
        for side, foot in feet.items()
    }
    wanted = {side: np.where(standing[side], -np.inf, heights[side]) for side in feet}
    lifted = np.array(q, dtype=np.float64)
    # A swing foot that dipped below the stance foot held the whole robot up (the base puts the
    # lowest point on the floor); lifted, the base comes down, and the foot is lifted again
    # from there (CMU 02_01: 0.65 of swing frames within 1 cm of the floor unlifted; one pass
    # 0.46, two 0.24, three 0.23, five 0.18).
    for _ in range(PASSES):
        again = lift_swing_feet(
            config,
            lifted,
            base.root_pos,
            base.root_quat,
            wanted,
            feet,
            motion.fps,
            solved=q,
            planted=standing,
        )
        if np.array_equal(again, lifted):
            break
        lifted = again
        base = floating_base(config, motion, lifted, trunk_frames=trunk_frames)
    return lifted, base
