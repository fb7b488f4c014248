"""Optimizer weights and options, read from a robot config's ``retarget`` mapping.

Every key is optional; the defaults were tuned on OP3 and Poppy with real mocap (see the
package docstring for the measurements). Per-bone twist limits are written
``twist_limit_deg.<CanonicalBone>``, e.g. ``twist_limit_deg.LeftForeArm: 120``, where the bone is
named by its canonical start joint.

Cost terms (all summed per frame):

- ``w_direction``   · Σ_bones |d(q) − d*|²   unit bone directions in the robot root frame
- ``w_orientation`` · Σ_bones |n(q) − n*|²   a unit normal of each bone (its roll about itself)
- ``w_end_effector``· Σ_ee w_ee |p(q) − p*|²  hand/foot/head positions (m), when given
- ``w_velocity``    · |(q_t − q_{t−1}) / dt|²                     (rad/s)²
- ``w_acceleration``· |(q_t − 2 q_{t−1} + q_{t−2}) / dt²|²         (rad/s²)²
- ``w_init``        · |q_t − q_init|²                              rad²
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from robot_retarget.errors import ConfigError

_TWIST_PREFIX = "twist_limit_deg."

# key → (default, lower bound inclusive, what it means)
_SCALARS: dict[str, tuple[float, float, str]] = {
    "w_direction": (1.0, 0.0, "bone-direction weight"),
    "w_orientation": (0.1, 0.0, "bone-orientation (roll) weight"),
    "w_end_effector": (10.0, 0.0, "end-effector position weight (1/m²)"),
    "w_velocity": (1e-5, 0.0, "velocity smoothness weight (s²/rad²)"),
    "w_acceleration": (1e-9, 0.0, "acceleration smoothness weight (s⁴/rad²)"),
    "w_init": (1e-4, 0.0, "pull toward the init pose (1/rad²)"),
    "twist_limit_deg": (100.0, 0.0, "default twist bound α of every bone (deg)"),
    "window": (16.0, 2.0, "offline window length (frames)"),
    "overlap": (2.0, 0.0, "offline window overlap (frames)"),
    "max_iter": (20.0, 1.0, "SQP iterations per online solve"),
    "offline_max_iter": (2.0, 1.0, "SQP iterations per offline window"),
}


@dataclass(frozen=True)
class RetargetSettings:
    """Validated optimizer settings (weights, twist bounds, offline windows)."""

    w_direction: float = 1.0
    w_orientation: float = 0.1
    w_end_effector: float = 10.0
    w_velocity: float = 1e-5
    w_acceleration: float = 1e-9
    w_init: float = 1e-4
    twist_limit_deg: float = 100.0
    twist_overrides_deg: Mapping[str, float] = field(default_factory=dict)
    window: int = 16
    overlap: int = 2
    max_iter: int = 20
    offline_max_iter: int = 2

    @classmethod
    def from_mapping(
        cls,
        values: Mapping[str, float],
        *,
        bone_names: tuple[str, ...] = (),
        path: str | None = None,
    ) -> RetargetSettings:
        """Validate ``values`` (a robot config's ``retarget`` section) and fill in defaults.

        ``bone_names`` are the canonical start joints of the robot's mapped bones; a twist
        override for any other bone is an error.
        """
        allowed = [*_SCALARS, *(_TWIST_PREFIX + b for b in bone_names)]
        scalars: dict[str, float] = {k: v[0] for k, v in _SCALARS.items()}
        overrides: dict[str, float] = {}
        for key, raw in values.items():
            if key.startswith(_TWIST_PREFIX) and key[len(_TWIST_PREFIX) :] in bone_names:
                overrides[key[len(_TWIST_PREFIX) :]] = _number(key, raw, 0.0, path, allowed)
            elif key in _SCALARS:
                scalars[key] = _number(key, raw, _SCALARS[key][1], path, allowed)
            else:
                raise ConfigError(
                    "unknown optimizer option", path=path, key=f"retarget.{key}",
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
        for key in ("window", "overlap", "max_iter", "offline_max_iter"):
            if scalars[key] != int(scalars[key]):
                raise ConfigError(
                    f"must be a whole number, got {scalars[key]}",
                    path=path,
                    key=f"retarget.{key}",
                    allowed="integers",
                )
        return cls(
            w_direction=scalars["w_direction"],
            w_orientation=scalars["w_orientation"],
            w_end_effector=scalars["w_end_effector"],
            w_velocity=scalars["w_velocity"],
            w_acceleration=scalars["w_acceleration"],
            w_init=scalars["w_init"],
            twist_limit_deg=scalars["twist_limit_deg"],
            twist_overrides_deg=dict(overrides),
            window=window,
            overlap=overlap,
            max_iter=int(scalars["max_iter"]),
            offline_max_iter=int(scalars["offline_max_iter"]),
        )

    def twist_limit_rad(self, bone: str) -> float:
        """Twist bound α of one bone (its canonical start joint), radians."""
        return math.radians(self.twist_overrides_deg.get(bone, self.twist_limit_deg))


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
