"""An opt-in One-Euro filter on the live input (``stream --one-euro MIN_HZ,BETA``).

A pose estimator's joints jitter by centimetres from frame to frame. The network and the
optimizer follow much of it, so the servos chatter: on performer 07 with the evaluation's jitter
(``eval-robot --corrupt jitter``), the robot's jerk rises 16× over clean input. The One-Euro
filter (Casiez, Roussel and Vogel, CHI 2012) is the usual cure in live tracking: a low-pass
whose cutoff rises with the signal's speed, so a still joint is smoothed hard and a fast one
follows with little lag. Here it runs per joint on the rotations (the speed is the angle to the
last filtered rotation per second; the filtered rotation moves toward the new one by slerp)
and on the root position, at the control rate, on the interpolated input.

It is off by default: it halves the jerk under jitter but its lag costs accuracy on clean input
(the README's "Live input, corrupted" has the measurements). ``reset`` starts over (the first
frame passes through): the loop resets it wherever a sequence starts.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat


@dataclass(frozen=True)
class OneEuroSettings:
    """``min_cutoff_hz``: the cutoff of a still signal; ``beta``: how much it rises per unit of
    speed (Hz per rad/s for rotations, per m/s for the root); ``d_cutoff_hz``: the cutoff of the
    speed estimate."""

    min_cutoff_hz: float = 2.0
    beta: float = 0.3
    d_cutoff_hz: float = 1.0

    def __post_init__(self) -> None:
        for name in ("min_cutoff_hz", "d_cutoff_hz"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"One-Euro {name} must be a positive number, got {value}")
        if not (math.isfinite(self.beta) and self.beta >= 0.0):
            raise ValueError(f"One-Euro beta must be a number ≥ 0, got {self.beta}")

    @classmethod
    def parse(cls, text: str) -> OneEuroSettings:
        """``"MIN_HZ,BETA"`` (the command line's form), e.g. ``"2,0.3"``."""
        parts = text.split(",")
        try:
            if len(parts) != 2:
                raise ValueError
            return cls(min_cutoff_hz=float(parts[0]), beta=float(parts[1]))
        except ValueError as exc:
            detail = f": {exc}" if str(exc) else ""
            raise ValueError(
                f"--one-euro takes MIN_HZ,BETA (e.g. 2,0.3), got {text!r}{detail}"
            ) from None


def one_euro_argument(text: str) -> OneEuroSettings:
    """argparse type of ``--one-euro MIN_HZ,BETA`` (``stream``, ``eval-robot --corrupt``)."""
    try:
        return OneEuroSettings.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _alpha(cutoff_hz: FloatArray | float, dt_s: float) -> FloatArray:
    """The smoothing factor of a first-order low-pass at ``cutoff_hz`` for a step of ``dt_s``."""
    tau = 1.0 / (2.0 * math.pi * np.asarray(cutoff_hz, dtype=np.float64))
    out: FloatArray = 1.0 / (1.0 + tau / dt_s)
    return out


class OneEuroFilter:
    """Filters canonical local rotations (J, 4) and a root position (3,), frame by frame."""

    def __init__(self, settings: OneEuroSettings) -> None:
        self.settings = settings
        self.reset()

    def reset(self) -> None:
        self._q: FloatArray | None = None
        self._root: FloatArray | None = None
        self._q_speed: FloatArray | None = None
        self._root_speed = 0.0

    def __call__(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike, dt_s: float
    ) -> tuple[FloatArray, FloatArray]:
        q = np.asarray(local_quats, dtype=np.float64)
        root = np.asarray(root_pos, dtype=np.float64)
        if not dt_s > 0.0:
            raise ValueError(f"dt_s must be positive, got {dt_s}")
        s = self.settings
        if self._q is None or self._root is None or self._q_speed is None:
            self._q, self._root = q.copy(), root.copy()
            self._q_speed = np.zeros(len(q))
            return self._q.copy(), self._root.copy()
        # Rotations: the angle to the last filtered rotation, as a speed, smoothed.
        cos_half = np.abs(np.sum(self._q * q, axis=-1)).clip(0.0, 1.0)
        speed = 2.0 * np.arccos(cos_half) / dt_s
        self._q_speed = self._q_speed + _alpha(s.d_cutoff_hz, dt_s) * (speed - self._q_speed)
        a = _alpha(s.min_cutoff_hz + s.beta * self._q_speed, dt_s)
        self._q = quat.slerp(self._q, q, a)
        # The root: the same on its position.
        root_speed = float(np.linalg.norm(root - self._root)) / dt_s
        self._root_speed += float(_alpha(s.d_cutoff_hz, dt_s)) * (root_speed - self._root_speed)
        a_root = float(_alpha(s.min_cutoff_hz + s.beta * self._root_speed, dt_s))
        self._root = self._root + a_root * (root - self._root)
        return self._q.copy(), self._root.copy()
