"""The residual model's parameters as numpy arrays: what its runtime file holds and its numpy
step (:mod:`robot_retarget.runtime.residual`) runs. Free of casadi and torch, so a training
machine without casadi can export a runtime file."""

from __future__ import annotations

from dataclasses import dataclass

from robot_retarget.array_types import FloatArray


@dataclass(frozen=True)
class ResidualWeights:
    """A residual model's parameters as float64 numpy arrays, for numpy twins of its step
    (here): every Linear as (weight, bias) in order."""

    denoiser_layers: tuple[tuple[FloatArray, FloatArray], ...]
    denoiser_history: int
    pose_mean: FloatArray
    pose_std: FloatArray
    rot_mean: FloatArray
    rot_std: FloatArray
    offset_mean: FloatArray
    offset_std: FloatArray
    correction_layers: tuple[tuple[FloatArray, FloatArray], ...]
    to_delta: tuple[FloatArray, FloatArray]
    max_correction_rad: float
    root_taps: FloatArray
    foot_lock: bool = False  # runtimes exported before the lock have none
