"""argparse types for counts and rates that must be positive (or, for warm-up counts, not
negative): a value out of range is refused as the command line is read (argparse's one-line
error naming the option), before it can divide by zero or empty an array somewhere deep in a
run. Every command's counts use these: train, eval, crossval, eval-robot, stream, doctor and the
benchmarks; train and crossval check their --device name here too."""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable


def _int_at_least(text: str, low: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < low:
        raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
    return value


def int_at_least(low: int) -> Callable[[str], int]:
    """The type of an integer ≥ ``low`` (a window of frames that needs two for velocities)."""

    def parse(text: str) -> int:
        return _int_at_least(text, low)

    parse.__name__ = f"int_at_least_{low}"
    return parse


def positive_int(text: str) -> int:
    """An integer ≥ 1 (frames, clips, steps)."""
    return _int_at_least(text, 1)


def non_negative_int(text: str) -> int:
    """An integer ≥ 0 (warm-up runs)."""
    return _int_at_least(text, 0)


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (a frame rate)."""
    value = _finite_float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number ≥ 0 (seconds left out)."""
    value = _finite_float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text}")
    return value


_DEVICE = re.compile(r"(cpu|cuda(:\d+)?|mps)")


def torch_device(text: str) -> str:
    """A torch device name (cpu, cuda, cuda:N, mps), checked as it is read: torch's own error
    for another comes as a traceback after the data have loaded. Whether the machine has the
    device is for the training to say."""
    if not _DEVICE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected cpu, cuda, cuda:N or mps, got {text!r}")
    return text
