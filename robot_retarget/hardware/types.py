"""The stage types at the hardware boundary: what goes to the servos and what comes back."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.errors import InvalidCommandError


def _float_vector(name: str, value: object) -> FloatArray:
    arr = np.array(value, dtype=np.float64)  # a private copy: frozen means frozen
    if arr.ndim != 1:
        raise InvalidCommandError(
            f"{name} must be a 1-D array (one value per joint), got shape {arr.shape}"
        )
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class JointCommand:
    """Joint angles to go to: ``q`` (J,) rad in the robot config's joint order, at time ``t_s``."""

    q: FloatArray
    t_s: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", _float_vector("JointCommand.q", self.q))
        # A time of inf would leave every later command "not after the previous" (a robot
        # stuck holding); NaN would compare false everywhere. Refused before anything sees it.
        try:
            t = float(self.t_s)
        except (TypeError, ValueError):
            raise InvalidCommandError(
                f"JointCommand.t_s must be a number, got {self.t_s!r}"
            ) from None
        if not math.isfinite(t):
            raise InvalidCommandError(
                f"JointCommand.t_s must be a finite number of seconds, got {t}: stamp each "
                "command with the time it is for"
            )
        object.__setattr__(self, "t_s", t)


@dataclass(frozen=True)
class JointState:
    """What the servos report, per joint in config order.

    ``q`` rad, ``velocity`` rad/s, ``load`` signed fraction of the servo's full load
    (−1…1), ``temperature`` °C, ``hardware_error`` the raw fault bits (0 = healthy), ``t_s`` the
    time the state was read (time.monotonic, s).
    """

    q: FloatArray
    velocity: FloatArray
    load: FloatArray
    temperature: FloatArray
    hardware_error: IntArray = field(repr=False)
    t_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("q", "velocity", "load", "temperature"):
            object.__setattr__(self, name, _float_vector(f"JointState.{name}", getattr(self, name)))
        err = np.array(self.hardware_error, dtype=np.int64)
        err.setflags(write=False)
        object.__setattr__(self, "hardware_error", err)
        n = self.q.shape[0]
        for name in ("velocity", "load", "temperature", "hardware_error"):
            if getattr(self, name).shape != (n,):
                raise InvalidCommandError(f"JointState.{name} must have shape ({n},)")
