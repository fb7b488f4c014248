"""Both feet held in double support: where the performer stands on both feet, the robot's
feet do not slide against each other.

The floating base pins a foot in stance by moving the whole robot (:mod:`floating_base`), and
with one foot down that holds it. With two down it cannot hold both: the legs follow the
performer's bone directions, a small humanoid's proportions are not a person's, and the feet
slide against each other while the performer's stay put. The base, pinned on the mean slip of
the points down, lets each foot slide by half of it (CMU 02, 05, 13 on OP3: per
double-support phase, the largest slide of one foot's points on the floor against the other's
was 2.38 cm at the 90th percentile; 91 % of the sliding under planted feet was in double
support).

So after the clip is solved, its swing feet lifted and its base placed, in each phase where the
performer stands on both feet, the two feet are moved back against each other by what their
points on the floor slid since the phase began (summed frame by frame over the points on the
floor in both frames, so a foot rolling onto its toes is held at its toes; each frame's slide
let go over ``HOLD_S``, so slow creep over a long stance is not held), each by half of it
and by its own leg's joints (those that move this foot and not the other): a damped
least-squares IK shifts the foot link horizontally and keeps its orientation and height
against the base (at most ``MAX_SHIFT_M`` between the feet, no joint more than
``MAX_CORRECTION_RAD``). Half each turns the legs least; a foot that stays in stance after the
phase has its correction faded out over ``FADE_S`` as the lifted one does, and the base's
pinning absorbs it. The corrections are smoothed over ``SMOOTH_S`` (held from the first frame,
a landing foot stopped dead and the joints' jerk rose by a quarter), clipped to the joints'
limits and speed limits, and the base is placed again. Only the legs' joints move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.pipeline.floating_base import (
    CONTACT_M,
    FloatingBase,
    floating_base,
    foot_points,
    foot_sides,
    planted_feet,
)
from robot_retarget.pipeline.swing_clearance import smooth
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics

MAX_SHIFT_M = 0.03  # the most the feet are moved against each other: more is not a slide
MAX_CORRECTION_RAD = 0.25  # the most any leg joint moves to hold a foot (14°)
# Gaussian σ of the joints' corrections. Chosen on OP3, tuning subjects 02 05 13 (skate under
# planted feet m/s / jerk rad/s³ / limb direction error): unsmoothed 0.026 / 1908 / 14.40°,
# 0.04 s 0.031 / 1523 / 14.39°, no hold 0.034 / 1520 / 14.10°.
SMOOTH_S = 0.04
FADE_S = 0.15  # a correction fades out over this once its phase is over
# A gap this short in the performer's contact (its test flickers for a frame or two in 168 of
# the 543 gaps between phases over the 70 clips) does not end a phase: ended, the correction
# built up so far fell to 0 within two frames and the feet slid back at once.
BRIDGE_S = 0.04
# A slide is held back over about this long (the time constant of a leaky sum), so slow creep
# over a long stance is let go: summed without a leak, a foot rocking heel to toe for 18 s (CMU
# 02_07, 02_10) ran up 8.8–11.2 cm of "slide" whose feet ended 1.4–3.4 cm from where they began.
# Chosen on OP3's tuning subjects 02 05 13 (slide per phase p90 cm / limb direction error):
# no leak 1.36 / 14.39°, 1 s 1.41 / 14.18°, 0.5 s 1.54 cm (unheld 2.38 / 14.10°).
HOLD_S = 1.0
ROTATION_WEIGHT_M = 0.2  # a foot turn of 1 rad weighs as much as a 0.2 m shift in the IK
_DAMPING = 1e-6  # Tikhonov term of the leg IK (m²): a near-singular knee's step stays finite
_MAX_STEP_RAD = 0.1  # no joint moves further in one Gauss-Newton step (the linear model's reach)
_ITERATIONS = 4  # Gauss-Newton steps per frame: a 1 cm shift to under 0.5 mm (p99)
_EPS_RAD = 1e-5  # finite-difference step of the leg Jacobian


@dataclass(frozen=True)
class Leg:
    """One side's leg: the joints that move its foot and not the other foot (``joints``), the
    link that carries the foot points (``link``), and their columns among
    :func:`~robot_retarget.pipeline.floating_base.foot_points` (``columns``)."""

    joints: IntArray
    link: str
    columns: tuple[int, ...]


def robot_legs(config: RobotConfig) -> dict[str, Leg]:
    """Per side ("Left", "Right"), the robot's leg (:class:`Leg`); empty unless the robot has
    feet on both sides, each on one link, with a joint that moves one foot and not the other."""
    sides = foot_sides(config)
    if set(sides) != {"Left", "Right"}:
        return {}
    points = foot_points(config)
    parents = {f.name: f.parent_link for f in config.frames}
    carried = RobotKinematics(config).carried_frames(points)  # (J, P)
    moved = {
        side: carried[:, [points.index(p) for p in names]].any(axis=1)
        for side, names in sides.items()
    }
    legs: dict[str, Leg] = {}
    for side, names in sides.items():
        other = "Right" if side == "Left" else "Left"
        joints = np.flatnonzero(moved[side] & ~moved[other])
        links = {parents.get(p) for p in names}
        if joints.size == 0 or len(links) != 1 or None in links:
            return {}
        legs[side] = Leg(
            joints.astype(np.int64),
            str(next(iter(links))),
            tuple(points.index(p) for p in names),
        )
    return legs


def phases(both_down: npt.ArrayLike, bridge: int = 0) -> list[tuple[int, int]]:
    """[start, stop) runs of True in ``both_down`` (T,), at least two frames long, two runs
    separated by at most ``bridge`` False frames joined into one."""
    flags = np.asarray(both_down, dtype=bool).astype(np.int8)
    edges = np.diff(np.concatenate([[0], flags, [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    runs: list[tuple[int, int]] = []
    for a, b in zip(starts, stops, strict=True):
        if runs and a - runs[-1][1] <= bridge:
            runs[-1] = (runs[-1][0], int(b))
        else:
            runs.append((int(a), int(b)))
    return [(a, b) for a, b in runs if b - a >= 2]


def bridge_frames(fps: float) -> int:
    """The longest gap (frames at ``fps``) that does not end a double-support phase."""
    return round(BRIDGE_S * fps)


def _rotation_error(target: FloatArray, got: FloatArray) -> FloatArray:
    """(…, 3) the small rotation vector turning ``got`` (…, 3, 3) onto ``target`` (…, 3, 3)."""
    r = target @ np.swapaxes(got, -1, -2)
    return 0.5 * np.stack(
        [r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]],
        axis=-1,
    )


def shift_feet(kin: RobotKinematics, q: FloatArray, leg: Leg, shift_root: FloatArray) -> FloatArray:
    """(N, J) ``q`` (N, J) with ``leg``'s joints moved so that its foot link is shifted by
    ``shift_root`` (N, 3) in the root frame and keeps its orientation (weighted least
    squares, ``ROTATION_WEIGHT_M``), limits not applied."""
    out = np.array(q, dtype=np.float64)
    rot0, pos0 = kin.frame_poses(out, [leg.link])
    target_rot, target_pos = rot0[:, 0], pos0[:, 0] + shift_root
    k = len(leg.joints)
    rows = np.arange(k)
    for _ in range(_ITERATIONS):
        tried = np.repeat(out[:, None, :], k + 1, axis=1)  # (N, k + 1, J)
        tried[:, rows + 1, leg.joints] += _EPS_RAD
        rot, pos = kin.frame_poses(tried, [leg.link])  # (N, k + 1, 1, …)
        rot, pos = rot[:, :, 0], pos[:, :, 0]
        jac_pos = (pos[:, 1:] - pos[:, :1]) / _EPS_RAD  # (N, k, 3)
        jac_rot = _rotation_error(rot[:, 1:], rot[:, :1]) / _EPS_RAD  # (N, k, 3)
        a = np.concatenate([jac_pos, ROTATION_WEIGHT_M * jac_rot], axis=-1)  # (N, k, 6)
        b = np.concatenate(
            [target_pos - pos[:, 0], ROTATION_WEIGHT_M * _rotation_error(target_rot, rot[:, 0])],
            axis=-1,
        )  # (N, 6)
        normal = a @ np.swapaxes(a, 1, 2) + _DAMPING * np.eye(k)  # (N, k, k)
        step = np.linalg.solve(normal, (a @ b[:, :, None]))[:, :, 0]
        # A step no joint takes further than MAX_STEP_RAD: the linear model's reach.
        largest = np.abs(step).max(axis=1, keepdims=True)
        step *= np.minimum(1.0, _MAX_STEP_RAD / np.maximum(largest, 1e-12))
        out[:, leg.joints] += step
    # No joint further than MAX_CORRECTION_RAD from where it was: a frame that needs more is
    # moved part of the way (its whole correction scaled down).
    change = out[:, leg.joints] - q[:, leg.joints]
    largest = np.abs(change).max(axis=1, keepdims=True)
    out[:, leg.joints] = q[:, leg.joints] + change * np.minimum(
        1.0, MAX_CORRECTION_RAD / np.maximum(largest, 1e-12)
    )
    return out


def _rate_limited(
    q: FloatArray, lower: FloatArray, upper: FloatArray, step: FloatArray
) -> FloatArray:
    """``q`` (T, J) inside [lower, upper] and changing by at most ``step`` (J,) a frame: each
    frame moves toward its target as far as the speed limit lets it (clip of a speed-bounded
    sequence to fixed bounds keeps the bound)."""
    out = np.clip(q, lower, upper)
    for t in range(1, len(out)):
        move = out[t] - out[t - 1]
        fast = np.abs(move) > step  # only these change: a + (b − a) is not always b
        out[t, fast] = out[t - 1, fast] + np.clip(move[fast], -step[fast], step[fast])
    return out


def _mean_slip(xy: FloatArray, down: npt.NDArray[np.bool_]) -> FloatArray:
    """(T, 2) per frame the mean horizontal move, since the frame before, of the points ``xy``
    (T, P, 2) that are ``down`` (T, P) in both frames; NaN where none is (and at frame 0)."""
    both = np.zeros_like(down)
    both[1:] = down[1:] & down[:-1]
    moves = np.zeros_like(xy)
    moves[1:] = xy[1:] - xy[:-1]
    count = both.sum(axis=1)
    total = (moves * both[:, :, None]).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count[:, None] > 0, total / count[:, None], np.nan)


def _phase_slides(
    legs: dict[str, Leg], feet: FloatArray, planted: npt.NDArray[np.bool_], fps: float
) -> list[tuple[int, int, FloatArray]]:
    """Per double-support phase (the performer stands on both feet, ``planted`` (T, F); a gap
    of ``bridge_frames`` or fewer does not end it): its [start, stop) and (stop − start, 2)
    per frame how far the left foot's points on the floor slid against the right foot's since
    the frame before, in the world (0 at the phase's first frame and where either foot has no
    point on the floor in both frames), for foot points ``feet`` (T, F, 3), world."""
    on_floor = (feet[:, :, 2] <= CONTACT_M) & planted
    slip = {
        side: _mean_slip(feet[:, list(leg.columns), :2], on_floor[:, list(leg.columns)])
        for side, leg in legs.items()
    }
    standing = [planted[:, list(leg.columns)].any(axis=1) for leg in legs.values()]
    out = []
    for start, stop in phases(standing[0] & standing[1], bridge_frames(fps)):
        slid = np.nan_to_num(slip["Left"][start:stop] - slip["Right"][start:stop])
        slid[0] = 0.0  # the feet are held from where the phase finds them
        out.append((start, stop, slid))
    return out


def _leaky_sum(values: FloatArray, keep: float) -> FloatArray:
    """(n, 2) running sums of ``values`` (n, 2) in which each frame first keeps ``keep`` of the
    sum so far (``keep`` 1: the cumulative sum)."""
    out = np.empty_like(values)
    total = np.zeros(values.shape[1:])
    for i, value in enumerate(values):
        total = keep * total + value
        out[i] = total
    return out


def hold_double_support(
    config: RobotConfig,
    motion: HumanMotion,
    q: npt.ArrayLike,
    base: FloatingBase,
    *,
    trunk_frames: npt.ArrayLike | None = None,
) -> tuple[FloatArray, FloatingBase]:
    """Joint angles (T, J) retargeted from ``motion`` (T frames at the same rate) with the feet
    of each double-support phase held against each other (module docstring), and
    the floating base placed again for them. ``base``: the base placed for ``q``;
    ``trunk_frames``: as :func:`~robot_retarget.pipeline.floating_base.floating_base`."""
    out = np.array(q, dtype=np.float64)
    legs = robot_legs(config)
    if len(out) < 2 or not legs:
        return out, base
    planted = planted_feet(config, motion.positions(), motion.fps)
    rot = quat.to_matrix(base.root_quat)  # (T, 3, 3) root-frame vectors → world
    kin = RobotKinematics(config)
    fade = max(1, round(FADE_S * motion.fps))
    delta = np.zeros_like(out)
    for start, stop, slid in _phase_slides(legs, base.feet, planted, motion.fps):
        span = slice(start, stop)
        # What the left foot must move against the right: the slides summed, each let go
        # over HOLD_S (a leaky sum), so that slow creep over a long stance is not held.
        apart = -_leaky_sum(slid, np.exp(-1.0 / (HOLD_S * motion.fps)))
        size = np.linalg.norm(apart, axis=1, keepdims=True)
        apart *= np.minimum(1.0, MAX_SHIFT_M / np.maximum(size, 1e-12))
        end = min(len(out), stop + fade)
        weight = 0.5 * (1.0 + np.cos(np.pi * np.arange(1, end - stop + 1) / (fade + 1)))
        for side, share in (("Left", 0.5), ("Right", -0.5)):  # half each: least turned
            leg = legs[side]
            shift = np.zeros((stop - start, 3))
            shift[:, :2] = share * apart
            shift_root = np.einsum("tji,tj->ti", rot[span], shift)  # world → root: Rᵀ v
            held = shift_feet(kin, out[span], leg, shift_root)
            delta[span, leg.joints] = held[:, leg.joints] - out[span][:, leg.joints]
            # Then fade out (a later phase's own correction overwrites this).
            delta[stop:end, leg.joints] = weight[:, None] * delta[stop - 1, leg.joints]
    if not delta.any():
        return out, base
    delta = np.stack([smooth(column, motion.fps, SMOOTH_S) for column in delta.T], axis=1)
    lower = np.asarray(config.lower, dtype=np.float64)
    upper = np.asarray(config.upper, dtype=np.float64)
    step = np.asarray(config.max_velocity, dtype=np.float64) / motion.fps
    held_q = _rate_limited(out + delta, lower, upper, step)
    return held_q, floating_base(config, motion, held_q, trunk_frames=trunk_frames)


def double_support_slides(
    config: RobotConfig, feet: npt.ArrayLike, planted: npt.ArrayLike, fps: float
) -> FloatArray:
    """(phases,) per double-support phase (the performer stands on both feet, ``planted``
    (T, F) from :func:`~robot_retarget.pipeline.floating_base.planted_feet`; a short gap does
    not end a phase, as in the hold), the furthest the left foot's points on the floor slid
    against the right foot's since the phase began (metres; summed as the hold sums them,
    without its leak), for robot foot points ``feet`` (T, F, 3) in the world at ``fps``, in
    :func:`~robot_retarget.pipeline.floating_base.foot_points` order. Empty when the robot has
    no two legs or the performer never stands on both feet."""
    f = np.asarray(feet, dtype=np.float64)
    down = np.asarray(planted, dtype=bool)
    legs = robot_legs(config)
    if not legs:
        return np.zeros(0)
    out = [
        np.linalg.norm(np.cumsum(slid, axis=0), axis=1).max(initial=0.0)
        for _, _, slid in _phase_slides(legs, f, down, fps)
    ]
    return np.asarray(out, dtype=np.float64)
