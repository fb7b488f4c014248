"""Optimizer weights and options, read from a robot config's ``retarget`` mapping.

Every key is optional; the defaults were tuned on OP3 and Poppy with real mocap (CMU subjects
02, 05, 13; see :mod:`robot_retarget.evaluation.robot` for the measurements). Per-bone values
are written ``<option>.<CanonicalBone>``, e.g. ``twist_limit_deg.LeftForeArm: 120`` or
``w_direction.LeftFoot: 0.1``, where the bone is named by its canonical start joint; they
replace the option's value for that bone (``twist_limit_deg``, ``w_direction``,
``w_orientation``).

Cost terms (all summed per frame; one :mod:`robot_retarget.optimize.terms` module each):

- ``w_direction``   · Σ_bones |d(q) − d*|²   unit bone directions in the robot root frame;
  ``direction_eps`` > 0: pseudo-Huber √(c² + eps²) − eps of each chord c instead of c².
  The feet default to 0.02 (an ankle at its limit must not pull the leg off its targets)
- ``w_orientation`` · Σ_bones |n(q) − n*|²   a unit normal of each bone (its roll about itself);
  0.01 (was 0.1): the roll fights the directions where a limb cannot match both (OP3's 3-joint
  arms and 3-axis hips: thigh / shin 7.1° / 5.9° → 4.9° / 5.0°; Poppy, ideal targets, CMU
  02/05/13: mean direction error 5.35° → 3.26°, its arm twist still followed)
- ``w_end_effector``· Σ_ee w_ee |p(q) − p*|²  hand/foot/head positions (m), when given
- ``w_keypoint``    · Σ_k |p_k(q) − p_root(q) − walked_k|²  elbows, wrists, knees, ankles from the
  target directions walked along the robot's bone lengths (m); 0 (off): on OP3 it raised the
  direction error (13.37° → 13.50° at 10, 14.31° at 50) and left the end-effector error alone
- ``w_velocity``    · |(q_t − q_{t−1}) / dt|²                     (rad/s)²
- ``w_acceleration``· |(q_t − 2 q_{t−1} + q_{t−2}) / dt²|²         (rad/s²)²
- ``w_init``        · |q_t − q_init|²                              rad²

Targets: ``level_feet`` (0 … 1, default 1) is the share of each foot's roll about its own long
axis left out of the targets (:mod:`robot_retarget.optimize.level_feet`): 1 keeps the soles
level, 0 copies the performer's foot roll, which on mocap rigs is mostly the rig's (OP3 stood
on the outer edges of its soles).

Solver options: ``max_iter`` (online SQP iterations), ``step_tol_ticks`` (the online SQP stops
once a step moves no joint by more than this share of the robot's finest servo tick),
``offline_max_iter``, ``window`` and ``overlap`` (offline windows), ``warm_start_step`` (where
each online solve starts: the last solution moved on by this share of its last step, clipped to
the frame's box).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from robot_retarget.errors import ConfigError

# key → (default, lower bound inclusive, what it means)
_SCALARS: dict[str, tuple[float, float, str]] = {
    "w_direction": (1.0, 0.0, "bone-direction weight"),
    "direction_eps": (
        0.0,
        0.0,
        "robust direction cost: chord where it turns from squared to linear",
    ),
    "w_orientation": (0.01, 0.0, "bone-orientation (roll) weight"),
    "w_end_effector": (10.0, 0.0, "end-effector position weight (1/m²)"),
    "w_keypoint": (0.0, 0.0, "limb keypoint weight (1/m²); 0: no keypoint term"),
    "w_velocity": (1e-5, 0.0, "velocity smoothness weight (s²/rad²)"),
    "w_acceleration": (1e-9, 0.0, "acceleration smoothness weight (s⁴/rad²)"),
    "w_init": (1e-4, 0.0, "pull toward the init pose (1/rad²)"),
    "twist_limit_deg": (100.0, 0.0, "default twist bound α of every bone (deg)"),
    "window": (16.0, 2.0, "offline window length (frames)"),
    "overlap": (2.0, 0.0, "offline window overlap (frames)"),
    "max_iter": (6.0, 1.0, "SQP iterations per online solve"),
    "offline_max_iter": (2.0, 1.0, "SQP iterations per offline window"),
    "step_tol_ticks": (
        0.33,
        0.0,
        "online SQP stops once its step moves no joint by more than this share of the "
        "robot's finest servo tick (0: only the cap and the KKT tolerances stop it)",
    ),
    "warm_start_step": (
        1.0,
        0.0,
        "online start point: the last solution moved on by this share of the last step",
    ),
    "level_feet": (
        1.0,
        0.0,
        "share (0 … 1) of each foot's roll about its long axis left out of the targets "
        "(1: soles level; 0: the performer's foot roll)",
    ),
}
_SHARES = ("level_feet",)  # at most 1
_INTEGERS = ("window", "overlap", "max_iter", "offline_max_iter")
# Per-bone values, written ``<prefix>.<CanonicalBone>`` (the bone's canonical start joint).
_PER_BONE: dict[str, str] = {
    "twist_limit_deg": "twist_overrides_deg",
    "w_direction": "direction_overrides",
    "w_orientation": "orientation_overrides",
}
# Per-bone defaults. The feet's directions: where an ankle limit stops a foot, a full weight pulls
# shin and thigh off their targets (OP3, ideal targets, CMU 02/05/13: thigh / shin error
# 2.88° / 2.86° → 1.68° / 1.51° at 0.02, jerk 2140 → 1105 rad/s³; Poppy 4.67° / 4.65° →
# 1.44° / 2.04°). Within the ankle's limits the foot still follows exactly.
_FOOT_DIRECTION = {"LeftFoot": 0.02, "RightFoot": 0.02}


@dataclass(frozen=True)
class RetargetSettings:
    """Validated optimizer settings (weights, twist bounds, offline windows)."""

    w_direction: float = 1.0
    direction_eps: float = 0.0
    w_orientation: float = 0.01
    w_end_effector: float = 10.0
    w_keypoint: float = 0.0
    w_velocity: float = 1e-5
    w_acceleration: float = 1e-9
    w_init: float = 1e-4
    twist_limit_deg: float = 100.0
    twist_overrides_deg: Mapping[str, float] = field(default_factory=dict)
    direction_overrides: Mapping[str, float] = field(default_factory=lambda: dict(_FOOT_DIRECTION))
    orientation_overrides: Mapping[str, float] = field(default_factory=dict)
    window: int = 16
    overlap: int = 2
    # 6, not 20 or 10: the frames that reach the cap sit where the cost is flat (a straight
    # limb at its joint limit, or lagging at its velocity limit); 20 doubled Poppy's worst
    # solves, and with the step tolerance below 6 took 9 % off its optimizer's p99 on the demo
    # (commands within 2.6e-3 rad). eval-robot scored the same at 20, 10 and 6 (at 6, Poppy's
    # direction and end-effector errors to every digit on all three sets, jerk −1 rad/s³).
    max_iter: int = 6
    # The online SQP also stops once a step moves no joint by more than a third of the finest
    # servo tick (a 4096-tick servo: 5.1e-4 rad). Where a limb lags at its velocity limit the
    # convexified Hessian makes the SQP converge linearly (each step ≈ 0.64 × the last, the
    # cost flat to 1e-6): Poppy's demo spent 4-10 iterations on 7.5 % of its frames moving
    # joints by less than a tick. Measured in `bench pipeline` and eval-robot (README, "Live
    # path").
    step_tol_ticks: float = 0.33
    offline_max_iter: int = 2
    # Each online solve starts from the last solution moved on by the last step (1.0; 0: from
    # the last solution): on 8 clips of CMU 02 and 07, SQP iterations per frame fell from
    # 1.98 to 1.36 (OP3) and 4.33 to 3.54 (Poppy), the median solve by 13 % and 21 %;
    # eval-robot on 02 05 13: OP3 unchanged, Poppy 5.64° / 0.144 → 5.54° / 0.141.
    warm_start_step: float = 1.0
    # The feet turned level about their long axis (robot_retarget.optimize.level_feet): the
    # mocap rig's foot roll had OP3 stand on its soles' outer edges (06 08 12, stance: median
    # 24.5° → 7.2° off flat; a foot-box corner > 1 cm under the floor in 51 % → 0.6 % of frames).
    level_feet: float = 1.0

    @classmethod
    def from_mapping(
        cls,
        values: Mapping[str, float],
        *,
        bone_names: tuple[str, ...] = (),
        path: str | None = None,
    ) -> RetargetSettings:
        """Validate ``values`` (a robot config's ``retarget`` section) and fill in defaults.

        ``bone_names`` are the canonical start joints of the robot's mapped bones; a per-bone
        value for any other bone is an error.
        """
        allowed = [*_SCALARS, *(f"{p}.{b}" for p in _PER_BONE for b in bone_names)]
        scalars: dict[str, float] = {k: v[0] for k, v in _SCALARS.items()}
        per_bone: dict[str, dict[str, float]] = {f: {} for f in _PER_BONE.values()}
        per_bone["direction_overrides"].update(_FOOT_DIRECTION)
        for key, raw in values.items():
            prefix, dot, bone = key.partition(".")
            if dot and prefix in _PER_BONE and bone in bone_names:
                per_bone[_PER_BONE[prefix]][bone] = _number(key, raw, 0.0, path, allowed)
            elif key in _SHARES:
                scalars[key] = _share(key, raw, path)
            elif key in _SCALARS:
                scalars[key] = _number(key, raw, _SCALARS[key][1], path, allowed)
            else:
                near = difflib.get_close_matches(key, allowed, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise ConfigError(
                    f"unknown optimizer option{hint}", path=path, key=f"retarget.{key}",
                    allowed=", ".join(allowed),
                )  # fmt: skip
        window = int(scalars["window"])
        overlap = int(scalars["overlap"])
        if overlap >= window:
            raise ConfigError(
                f"overlap ({overlap}) must be smaller than window ({window})",
                path=path,
                key="retarget.overlap",
                allowed=f"0 … {window - 1}",
            )
        for key in _INTEGERS:
            if scalars[key] != int(scalars[key]):
                raise ConfigError(
                    f"must be a whole number, got {scalars[key]}",
                    path=path,
                    key=f"retarget.{key}",
                    allowed="integers",
                )
        ints = {k: int(scalars.pop(k)) for k in _INTEGERS}
        return cls(**scalars, **ints, **per_bone)  # type: ignore[arg-type]

    def twist_limit_rad(self, bone: str) -> float:
        """Twist bound α of one bone (its canonical start joint), radians."""
        return math.radians(self.twist_overrides_deg.get(bone, self.twist_limit_deg))

    def direction_weight(self, bone: str) -> float:
        """Direction weight of one bone (its canonical start joint)."""
        return self.direction_overrides.get(bone, self.w_direction)

    def orientation_weight(self, bone: str) -> float:
        """Orientation (roll) weight of one bone (its canonical start joint)."""
        return self.orientation_overrides.get(bone, self.w_orientation)


def _share(key: str, raw: object, path: str | None) -> float:
    """A share 0 … 1 (``level_feet``, the only one): true/false gets the number to write."""
    allowed = "a number 0 … 1 (1: soles level, 0: the performer's foot roll)"
    if isinstance(raw, bool):
        raise ConfigError(
            f"must be a number, got {raw!r}: write {int(raw)} ({'on' if raw else 'off'})",
            path=path, key=f"retarget.{key}", allowed=allowed,
        )  # fmt: skip
    value = float(raw) if isinstance(raw, (int, float)) else math.nan
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ConfigError(
            f"must be a share 0 … 1, got {raw!r}", path=path, key=f"retarget.{key}",
            allowed=allowed,
        )  # fmt: skip
    return value


def _number(key: str, raw: object, lower: float, path: str | None, allowed: list[str]) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise ConfigError(
            f"must be a number, got {raw!r}", path=path, key=f"retarget.{key}",
            allowed=", ".join(allowed),
        )  # fmt: skip
    value = float(raw)
    if not math.isfinite(value) or value < lower:
        raise ConfigError(
            f"must be finite and ≥ {lower:g}, got {value}",
            path=path,
            key=f"retarget.{key}",
            allowed=f"numbers ≥ {lower:g}",
        )
    return value
