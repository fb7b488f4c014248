"""Feet kept level about their own long axis: the mocap rig's foot roll left out of the targets.

A foot joint's roll about the foot's long axis (heel to toe) is what a motion-capture rig makes
of it, not what the foot does: in stance a performer's sole lies flat on the floor, but on the
CMU clips the foot joint's lateral axis stands 17–22° out of the horizontal there (02_01,
06_10; outwards on both feet), and OP3, whose ankle roll copies it, stood on the outer edges of
its soles (median 24.5° off flat in stance on 06, 08 and 12; in 51 % of those frames a corner
of the manufacturer's foot boxes was more than 1 cm under the floor; 7.2° and 0.6 % level).

So each foot's global rotation is turned about its own long axis until its lateral axis (the
canonical left, made perpendicular to the rest axis) is horizontal: ``share`` of that roll
angle (``retarget.level_feet``, 1 by default). Its long axis — where the toes point, the foot
bone's direction target — does not move, only the roll about it; the joints below the foot
(the toes) turn with it. A foot within 17° of vertical (on tiptoe, a kick straight up) has no
"level": there nothing is turned, and between 17° and 44° from vertical the turn fades in. Nor
is a roll of more than 45° the rig's: it fades out by 90° (a foot pitched back past vertical,
in a kneel or an arabesque, is "rolled" 180° by construction), so the turn never jumps.

Two implementations of the same numbers: :func:`level_twists` (numpy, any leading shape:
whole clips and the live path's degenerate frames, through :func:`level_globals`) and
:func:`level_twists_sx` (the live path's compiled targets graph); tested against each other.
Quaternions need not be of unit length (both normalise them first).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    Joint,
    default_canonical_skeleton,
)

# |up × long axis| (the sine of the foot's angle from vertical): below FADE_START nothing is
# turned, above FADE_FULL the whole ``share``; between, linearly.
FADE_START = 0.3  # 17.5° from vertical
FADE_FULL = 0.7  # 44.4° from vertical
# |roll| up to ROLL_FULL is turned in full, from ROLL_NONE on not at all; between, linearly.
ROLL_FULL = math.radians(45.0)
ROLL_NONE = math.radians(90.0)
_UP = np.array([0.0, 1.0, 0.0])  # canonical up (Y)
_LEFT = np.array([1.0, 0.0, 0.0])  # canonical left (X): a foot's lateral axis at rest
FEET = ((Joint.LeftFoot, Joint.LeftToeBase), (Joint.RightFoot, Joint.RightToeBase))


def _descendants(joint: int) -> tuple[int, ...]:
    """``joint`` and every joint below it in the canonical tree."""
    out = [joint]
    for j in range(len(CANONICAL_JOINTS)):
        k = CANONICAL_PARENTS[j]
        while k >= 0 and j not in out:
            if k == joint:
                out.append(j)
            k = CANONICAL_PARENTS[k]
    return tuple(sorted(out))


@dataclass(frozen=True, eq=False)  # holds arrays
class FootLevel:
    """Which joints turn with each foot, and each foot's rest long axis (canonical, unit)."""

    share: float
    turned: tuple[tuple[int, ...], ...]  # per foot: the foot joint and the joints below it
    rest_axes: FloatArray  # (2, 3) heel → toe at rest, in the foot joint's frame

    @property
    def feet(self) -> tuple[int, ...]:
        return tuple(int(f) for f, _ in FEET)

    def __post_init__(self) -> None:
        object.__setattr__(self, "share", check_share(self.share))

    @classmethod
    def of_skeleton(cls, offsets: npt.ArrayLike, share: float) -> FootLevel:
        """From a canonical skeleton's joint offsets (22, 3): each foot's rest axis is its toe
        joint's offset (a toe joint on its foot: the reference skeleton's direction)."""
        off = np.asarray(offsets, dtype=np.float64)
        reference = default_canonical_skeleton().offsets
        axes = []
        for _, toe in FEET:
            v = off[toe] if np.linalg.norm(off[toe]) > 1e-9 else reference[toe]
            axes.append(v / np.linalg.norm(v))
        return cls.of_axes(np.array(axes), share)

    @classmethod
    def of_axes(cls, rest_axes: npt.ArrayLike, share: float) -> FootLevel:
        """From the feet's rest axes (2, 3), or per frame (…, 2, 3) (:func:`rest_axes_of`)."""
        axes = np.asarray(rest_axes, dtype=np.float64)
        return cls(share, tuple(_descendants(int(f)) for f, _ in FEET), axes)


def check_share(share: float) -> float:
    """``share`` as a float in [0, 1], else ValueError (``retarget.level_feet``'s range)."""
    value = float(share)
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ValueError(
            f"level_feet must be a share 0 … 1 (1: soles level, 0: the performer's foot roll), "
            f"got {share!r}"
        )
    return value


def _fade(sine: FloatArray, roll: FloatArray, share: float) -> FloatArray:
    """The share of ``roll`` turned: ``share``, faded near vertical and for large rolls."""
    upright = np.clip((sine - FADE_START) / (FADE_FULL - FADE_START), 0.0, 1.0)
    small = np.clip((ROLL_NONE - np.abs(roll)) / (ROLL_NONE - ROLL_FULL), 0.0, 1.0)
    return np.asarray(share * upright * small, dtype=np.float64)


def _fade_sx(sine: ca.SX, roll: ca.SX, share: float) -> ca.SX:
    upright = ca.fmin(ca.fmax((sine - FADE_START) / (FADE_FULL - FADE_START), 0.0), 1.0)
    small = ca.fmin(ca.fmax((ROLL_NONE - ca.fabs(roll)) / (ROLL_NONE - ROLL_FULL), 0.0), 1.0)
    return share * upright * small


def _unit_or_identity(q: FloatArray) -> FloatArray:
    """``q / |q|``, the identity where |q| ≤ 1e-12 (as ``symbolic_quaternion.unit_or_identity``):
    a degenerate frame goes on to the targets' own fallbacks instead of raising here."""
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    ok = n > 1e-12
    return np.where(ok, q / np.where(ok, n, 1.0), quat.identity(q.shape[:-1]))


def _rest_lateral(rest_axis: FloatArray) -> FloatArray:
    """Canonical left made perpendicular to the rest axis (…, 3), unit."""
    v = _LEFT - (rest_axis @ _LEFT)[..., None] * rest_axis
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=np.float64)


def level_twists(foot_globals: npt.ArrayLike, rest_axes: npt.ArrayLike, share: float) -> FloatArray:
    """Turns (…, 4) about each foot's long axis that level it: ``turn ⊗ G`` is the leveled
    global rotation of a foot whose global rotation is ``G`` (…, 4) and rest long axis
    ``rest_axes`` (…, 3) (unit, in the foot's frame)."""
    g = _unit_or_identity(np.asarray(foot_globals, dtype=np.float64))
    r = np.broadcast_to(np.asarray(rest_axes, dtype=np.float64), (*g.shape[:-1], 3))
    axis = quat.rotate(g, r)  # the long axis in the world
    lateral = quat.rotate(g, _rest_lateral(r))  # ⟂ axis
    level = np.cross(_UP, axis)  # the horizontal lateral axis ⟂ axis (canonical left at rest)
    sine = np.linalg.norm(level, axis=-1)
    level = level / np.maximum(sine, 1e-12)[..., None]
    # The roll: the signed angle about the axis from lateral to level (both ⟂ axis).
    roll = np.arctan2(
        np.sum(np.cross(lateral, level) * axis, axis=-1), np.sum(lateral * level, axis=-1)
    )
    half = 0.5 * _fade(sine, roll, share) * roll
    return np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * axis], axis=-1)


def level_globals(level: FootLevel, global_quats: npt.ArrayLike) -> FloatArray:
    """Global rotations (…, 22, 4) with each foot and the joints below it turned level."""
    g = np.array(global_quats, dtype=np.float64)
    twists = level_twists(g[..., list(level.feet), :], level.rest_axes, level.share)
    for k, joints in enumerate(level.turned):
        g[..., list(joints), :] = quat.mul(twists[..., k : k + 1, :], g[..., list(joints), :])
    return g


def rest_axes_of(positions: npt.ArrayLike, global_quats: npt.ArrayLike) -> FloatArray:
    """(…, 2, 3) each foot's long axis in its own frame, from global positions (…, 22, 3) and
    rotations (…, 22, 4): the heel → toe line as the motion has it (for motions without their
    skeleton at hand, e.g. ``targets_from_globals``)."""
    p = np.asarray(positions, dtype=np.float64)
    g = _unit_or_identity(np.asarray(global_quats, dtype=np.float64))
    feet = [int(f) for f, _ in FEET]
    toes = [int(t) for _, t in FEET]
    world = p[..., toes, :] - p[..., feet, :]
    world = world / np.maximum(np.linalg.norm(world, axis=-1, keepdims=True), 1e-12)
    return quat.rotate(quat.conjugate(g[..., feet, :]), world)


def level_twists_sx(level: FootLevel, foot_globals: Sequence[sq.Quat]) -> list[sq.Quat]:
    """:func:`level_twists` in SX, one turn per foot (for the compiled targets graph)."""
    out: list[sq.Quat] = []
    for g, r in zip(foot_globals, level.rest_axes, strict=True):
        m = sq.matrix(sq.unit_or_identity(g))
        axis = sq.rotate(m, tuple(ca.SX(float(c)) for c in r))
        lateral = sq.rotate(m, tuple(ca.SX(float(c)) for c in _rest_lateral(r)))
        raw = sq.cross(tuple(ca.SX(c) for c in _UP), axis)
        sine = sq.norm(raw)
        level_axis = sq.scale(1.0 / ca.fmax(sine, 1e-12), raw)
        roll = ca.atan2(sq.dot(sq.cross(lateral, level_axis), axis), sq.dot(lateral, level_axis))
        half = 0.5 * _fade_sx(sine, roll, level.share) * roll
        s_half = ca.sin(half)
        out.append((ca.cos(half), s_half * axis[0], s_half * axis[1], s_half * axis[2]))
    return out
