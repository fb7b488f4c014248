"""Joint angles (rad, robot convention) ↔ servo position ticks, per joint and for a whole robot.

The servo sees ``servo_rad = direction * q + zero_offset_rad`` (see ``robot.config``) and
reports ``tick = zero_tick + servo_rad / rad_per_tick``: XM430-W350, MX-28, MX-64 have 4096
ticks per turn with 2048 at 0 rad; the AX-12A has 1024 ticks over 300° with 512 at 0 rad.
Values the servo cannot reach raise :class:`~robot_retarget.errors.ServoRangeError`; nothing is
ever wrapped or clamped here (clamping to joint limits is the safety layer's job).

Velocities: the speed registers count in model-specific steps (Profile Velocity of the
XM430: 0.229 rpm; Moving Speed of MX (Protocol 1.0): 0.114 rpm; AX-12A: 0.111 rpm, ROBOTIS
e-Manuals), and 0 means "no limit / maximum speed" on all of them, so a requested speed
always maps to at least 1 step.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray, IntArray
from robot_retarget.errors import ServoRangeError
from robot_retarget.robot.config import JointConfig, RobotConfig
from robot_retarget.robot.servo_models import RPM_TO_RAD_S, ServoModel, servo_model

# Speed register resolution per model (rpm per step), ROBOTIS e-Manuals.
VELOCITY_STEP_RPM: dict[str, float] = {
    "XM430-W350": 0.229,  # Profile Velocity (112) / Velocity Limit (44)
    "MX-28": 0.114,  # Moving Speed (32), Protocol 1.0 firmware
    "MX-64": 0.114,
    "AX-12A": 0.111,
}
# Largest value the speed register takes (XM430 Profile Velocity is 32 bit, but its useful range
# ends at the Velocity Limit register's maximum, 1023; Protocol 1.0 Moving Speed is 0–1023).
VELOCITY_MAX_STEPS = 1023
# A limit that falls on a tick to within rounding noise keeps that tick.
_TICK_EPS = 1e-9


def servo_tick_range(model: ServoModel) -> tuple[int, int]:
    """The (lowest, highest) position tick of a model."""
    return model.min_tick, model.max_tick


def servo_rad_range(model: ServoModel) -> tuple[float, float]:
    """The (lowest, highest) servo angle in rad (servo convention, 0 = horn centre)."""
    return (
        (model.min_tick - model.zero_tick) * model.rad_per_tick,
        (model.max_tick - model.zero_tick) * model.rad_per_tick,
    )


def joint_rad_range(joint: JointConfig) -> tuple[float, float]:
    """The (lowest, highest) joint angle q in rad (robot convention) the joint's servo reaches."""
    lo, hi = servo_rad_range(servo_model(joint.servo_model))
    a = (lo - joint.zero_offset_rad) * joint.direction
    b = (hi - joint.zero_offset_rad) * joint.direction
    return (a, b) if a <= b else (b, a)


class JointServoUnits:
    """Conversions for one joint: its servo model, direction and zero offset."""

    def __init__(self, joint: JointConfig) -> None:
        self.joint = joint
        self.model = servo_model(joint.servo_model)
        self.rad_range = joint_rad_range(joint)
        self.tick_range = servo_tick_range(self.model)

    def to_tick(self, q_rad: float) -> int:
        """The tick for joint angle ``q_rad``; ServoRangeError when the servo cannot reach it."""
        m = self.model
        tick = float(np.rint(self._exact_tick(q_rad)))
        if not (np.isfinite(tick) and m.min_tick <= tick <= m.max_tick):
            raise _rad_error(self, float(q_rad))
        return int(tick)

    def _exact_tick(self, q_rad: float) -> float:
        """The (fractional) tick of joint angle ``q_rad``: direction and zero offset applied."""
        j, m = self.joint, self.model
        return (j.direction * q_rad + j.zero_offset_rad) / m.rad_per_tick + m.zero_tick

    def limit_ticks(self) -> tuple[int, int]:
        """The lowest and highest tick inside the joint's limits (direction and zero offset
        applied; rounded inward, so that no tick of the range is a hair past a limit)."""
        j, m = self.joint, self.model
        ends = [self._exact_tick(q) for q in (j.lower_rad, j.upper_rad)]
        lo = max(m.min_tick, math.ceil(min(ends) - _TICK_EPS))
        hi = min(m.max_tick, math.floor(max(ends) + _TICK_EPS))
        if lo > hi:  # limits narrower than a tick: the one nearest their middle
            lo = hi = int(np.clip(round(0.5 * (ends[0] + ends[1])), m.min_tick, m.max_tick))
        return lo, hi

    def from_tick(self, tick: int) -> float:
        """The joint angle (rad) for a tick; ServoRangeError outside the model's tick range."""
        j, m = self.joint, self.model
        if not m.min_tick <= int(tick) <= m.max_tick:
            raise _tick_error(self, int(tick))
        servo = (int(tick) - m.zero_tick) * m.rad_per_tick
        return float((servo - j.zero_offset_rad) * j.direction)


class ServoUnits:
    """Vector conversions over all joints of a config, in config joint order.

    ``to_ticks(q)`` and ``from_ticks(ticks)`` accept leading batch dimensions: (…, J).
    """

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        self.joints = tuple(JointServoUnits(j) for j in config.joints)
        self.direction = np.array([j.direction for j in config.joints], dtype=np.float64)
        self.zero_offset_rad = np.array([j.zero_offset_rad for j in config.joints])
        models = [u.model for u in self.joints]
        self.zero_tick = np.array([m.zero_tick for m in models], dtype=np.int64)
        self.rad_per_tick = np.array([m.rad_per_tick for m in models])
        self.max_tick = np.array([m.max_tick for m in models], dtype=np.int64)
        self.lower_rad = np.array([u.rad_range[0] for u in self.joints])
        self.upper_rad = np.array([u.rad_range[1] for u in self.joints])
        limit_ticks = np.array([u.limit_ticks() for u in self.joints], dtype=np.int64)
        self.limit_lo_tick, self.limit_hi_tick = limit_ticks[:, 0], limit_ticks[:, 1]
        self.velocity_step_rad_s = np.array(
            [VELOCITY_STEP_RPM[m.name] * RPM_TO_RAD_S for m in models]
        )

    @property
    def num_joints(self) -> int:
        return len(self.joints)

    def to_ticks(self, q_rad: npt.ArrayLike) -> IntArray:
        """Position ticks (…, J) for joint angles (…, J) in rad."""
        q = self._check_shape(q_rad, "joint angles")
        servo = q * self.direction + self.zero_offset_rad
        ticks = np.rint(servo / self.rad_per_tick) + self.zero_tick
        bad = ~np.isfinite(ticks) | (ticks < 0) | (ticks > self.max_tick)
        if np.any(bad):
            j, value = _first_bad(q, bad)
            raise _rad_error(self.joints[j], float(value))
        return ticks.astype(np.int64)

    def from_ticks(self, ticks: npt.ArrayLike) -> FloatArray:
        """Joint angles (…, J) in rad for position ticks (…, J)."""
        t = np.asarray(ticks)
        if t.shape[-1:] != (self.num_joints,):
            raise ValueError(f"ticks need a last axis of {self.num_joints} joints, got {t.shape}")
        if not np.issubdtype(t.dtype, np.integer):
            raise TypeError(f"ticks must be integers, got dtype {t.dtype}")
        t = t.astype(np.int64)
        bad = (t < 0) | (t > self.max_tick)
        if np.any(bad):
            j, value = _first_bad(t, bad)
            raise _tick_error(self.joints[j], int(value))
        servo = (t - self.zero_tick) * self.rad_per_tick
        return np.asarray((servo - self.zero_offset_rad) * self.direction, dtype=np.float64)

    def velocity_to_steps(self, velocity_rad_s: npt.ArrayLike) -> IntArray:
        """Speed register values (…, J) for joint speeds (…, J) in rad/s (sign ignored).

        Rounds to the nearest step but never to 0 (which means "no limit" on the servo);
        speeds beyond the register's range raise ServoRangeError.
        """
        v = np.abs(self._check_shape(velocity_rad_s, "joint speeds"))
        steps = np.maximum(np.rint(v / self.velocity_step_rad_s), 1.0)
        bad = ~np.isfinite(steps) | (steps > VELOCITY_MAX_STEPS)
        if np.any(bad):
            j, value = _first_bad(v, bad)
            top = VELOCITY_MAX_STEPS * float(self.velocity_step_rad_s[j])
            raise ServoRangeError(
                f"joint {self.joints[j].joint.name}: speed {value:.4g} rad/s exceeds the speed "
                f"register's range (≤ {top:.4g} rad/s)",
                joint=self.joints[j].joint.name,
                value=value,
                valid_range=(0.0, top),
                unit="rad/s",
            )
        return steps.astype(np.int64)

    def velocity_from_steps(self, steps: npt.ArrayLike) -> FloatArray:
        """Joint speeds (…, J) in rad/s for speed register values (…, J)."""
        s = np.asarray(steps)
        if s.shape[-1:] != (self.num_joints,):
            raise ValueError(f"steps need a last axis of {self.num_joints} joints, got {s.shape}")
        return np.asarray(s * self.velocity_step_rad_s, dtype=np.float64)

    def _check_shape(self, values: npt.ArrayLike, what: str) -> FloatArray:
        a = np.asarray(values, dtype=np.float64)
        if a.shape[-1:] != (self.num_joints,):
            raise ValueError(f"{what} need a last axis of {self.num_joints} joints, got {a.shape}")
        return a


def _rad_error(unit: JointServoUnits, value: float) -> ServoRangeError:
    lo, hi = unit.rad_range
    j = unit.joint
    return ServoRangeError(
        f"joint {j.name}: {value!r} rad is outside what its {unit.model.name} can reach "
        f"({lo:.6f} … {hi:.6f} rad with direction {j.direction:+d} and zero offset "
        f"{j.zero_offset_rad:.6f} rad); limit the command upstream, never wrap it",
        joint=j.name,
        value=value,
        valid_range=(lo, hi),
        unit="rad",
    )


def _tick_error(unit: JointServoUnits, tick: int) -> ServoRangeError:
    lo, hi = unit.tick_range
    return ServoRangeError(
        f"joint {unit.joint.name}: tick {tick} is outside the {unit.model.name}'s range "
        f"{lo}…{hi}; check the servo model configured for this joint",
        joint=unit.joint.name,
        value=float(tick),
        valid_range=(float(lo), float(hi)),
        unit="tick",
    )


def _first_bad(values: npt.NDArray[np.generic], bad: npt.NDArray[np.bool_]) -> tuple[int, float]:
    """(joint index, value) of the first flagged entry of a (…, J) array."""
    where = tuple(int(i) for i in np.argwhere(bad)[0])
    return where[-1], float(values[where])
