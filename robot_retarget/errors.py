"""One error hierarchy for the whole project.

Every error carries the values that caused it as attributes, and its message says what the user
can do next. Catch :class:`RetargetError` to catch everything the library raises on purpose.
"""

from __future__ import annotations

from pathlib import Path


class RetargetError(Exception):
    """Root of every error robot-retarget raises on purpose."""


class ConfigError(RetargetError):
    """A robot configuration (YAML) is wrong: names the file, the key and what was allowed."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        key: str | None = None,
        allowed: str | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.key = key
        self.allowed = allowed
        self.message = message
        parts = []
        if self.path is not None:
            parts.append(self.path)
        if key is not None:
            parts.append(f"key '{key}'")
        prefix = ": ".join(parts)
        text = f"{prefix}: {message}" if prefix else message
        if allowed is not None:
            text += f" (allowed: {allowed})"
        super().__init__(text)


class MotionFormatError(RetargetError):
    """A motion file (BVH, trajectory CSV/JSON/NPZ) cannot be read: names the file and line."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        line: int | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.line = line
        where = self.path or "<motion>"
        if line is not None:
            where += f", line {line}"
        super().__init__(f"{where}: {message}")


class OutputWriteError(MotionFormatError, OSError):
    """An output file could not be written (its folder is missing, not writable, the disk is
    full): a RetargetError naming the file, and an OSError, so that code which saves
    elsewhere when a write fails (stream's recording) still catches it."""


class JointMappingError(MotionFormatError):
    """A skeleton's joints cannot be mapped onto the canonical human skeleton."""

    def __init__(
        self,
        message: str,
        *,
        missing: tuple[str, ...] = (),
        path: str | Path | None = None,
    ) -> None:
        self.missing = missing
        super().__init__(message, path=path)


class SourceError(RetargetError):
    """A live motion source (UDP, TCP, replay) failed or sent something unusable."""


class ModelLoadError(RetargetError):
    """A retargeting model or checkpoint could not be loaded: names the file and/or model."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        model: str | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.model = model
        self.reason = message
        super().__init__(f"{self.path}: {message}" if self.path is not None else message)


class SolveError(RetargetError):
    """The retargeting optimizer got invalid input (NaN, wrong shape) and produced no command."""


class HardwareError(RetargetError):
    """Something went wrong talking to the robot."""


class InvalidCommandError(HardwareError, ValueError):
    """A joint command or state built from values none has (a wrong shape, a time that is not
    a finite number): a HardwareError, and a ValueError as it always was."""


class CommunicationError(HardwareError):
    """A bus transaction failed (timeout, corrupt packet); retryable."""


class ServoFaultError(HardwareError):
    """A servo reported a hardware error; never retried, torque goes off."""

    def __init__(self, message: str, *, servo_id: int, bits: tuple[str, ...] = ()) -> None:
        self.servo_id = servo_id
        self.bits = bits
        super().__init__(message)


class InvalidMotionError(RetargetError, ValueError):
    """A motion built from values no motion has (a wrong shape, NaN, a non-unit quaternion, a
    frame rate of 0): a RetargetError, and a ValueError as it always was."""


class ServoRangeError(RetargetError, ValueError):
    """A joint angle (or tick value) lies outside what its servo can reach; never wrapped or
    clamped silently. ``value`` is in the unit named by ``unit`` ("rad" or "tick") and
    ``valid_range`` is the (low, high) interval in that unit."""

    def __init__(
        self, message: str, *, joint: str, value: float, valid_range: tuple[float, float], unit: str
    ) -> None:
        self.joint = joint
        self.value = value
        self.valid_range = valid_range
        self.unit = unit
        super().__init__(message)
