"""numpy twin of the copy baselines' online step (no torch on the live path).

The ``copy`` and ``copy-scaled`` models (:mod:`robot_retarget.nn.models.copy`) only pass the
rotations through and re-integrate the root; running them through torch costs ~0.35 ms per
frame in tensor-op overhead. :class:`FastCopyRetargeter` does the same arithmetic on Python
floats, step for step as ``RetargetModel.step`` with its ``FeatureStream`` (heading from the
root's +X column, heading-free root velocity, optional height-ratio scaling, integration from
the source's first root position and heading, heading put back on the root rotation), so its
output equals :class:`robot_retarget.nn.inference.OnlineRetargeter`'s to rounding (tested).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import numpy.typing as npt

from robot_retarget.nn.inference import LoadedModel, OnlineRetargeter
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.copy import CopyModel, CopyScaledModel
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.skeleton import Skeleton

FloatArray = npt.NDArray[np.float64]

_J = len(CANONICAL_JOINTS)
_TWO_PI = 2.0 * math.pi


class OnlineStep(Protocol):
    """What the live step needs from a network: per-frame ``step`` and ``reset``."""

    def reset(self) -> None: ...

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]: ...


def rest_height_m(offsets: FloatArray) -> float:
    """Vertical extent of a canonical skeleton's rest pose (``nn.features.skeleton_height``)."""
    pos = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets).rest_positions()
    return float(pos[:, 1].max() - pos[:, 1].min())


def _check(name: str, a: FloatArray, shape: tuple[int, ...]) -> None:
    # Same error as OnlineRetargeter, so callers see one behaviour whichever path runs.
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")


class FastCopyRetargeter:
    """Online ``copy`` / ``copy-scaled`` on numpy: ``step`` (22, 4), (3,) → (22, 4), (3,).

    ``velocity_scale`` multiplies the root's x, y, z velocity (1.0 for ``copy``); use
    :func:`online_retargeter` to get the right one for a model.
    """

    def __init__(
        self, source_offsets: npt.ArrayLike, target_offsets: npt.ArrayLike, velocity_scale: float
    ) -> None:
        src = np.asarray(source_offsets, dtype=np.float64)
        tgt = np.asarray(target_offsets, dtype=np.float64)
        _check("source_offsets", src, (_J, 3))
        _check("target_offsets", tgt, (_J, 3))
        self.velocity_scale = float(velocity_scale)
        self.reset()

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self._prev: tuple[float, float, float, float] | None = None  # x, y, z, yaw
        self._out: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q = np.array(local_quats, dtype=np.float64)  # a copy: the root entry is rewritten
        root = np.asarray(root_pos, dtype=np.float64)
        _check("local_quats", q, (_J, 4))
        _check("root_pos", root, (3,))
        w, x, y, z = q[0].tolist()
        px, py, pz = root.tolist()
        # Heading of the root's +X column (FrameKinematics' quadratic form), as FeatureStream.
        yaw = math.atan2(-2.0 * (x * z - w * y), w * w + x * x - y * y - z * z)
        prev = self._prev
        self._prev = (px, py, pz, yaw)
        if prev is None:  # frame 0: the output starts at the source's root and heading
            self._out = (px, py, pz, yaw)
            out_x, out_y, out_z, out_yaw = self._out
        else:
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy, dz = px - prev[0], py - prev[1], pz - prev[2]
            k = self.velocity_scale
            vx, vy, vz = (c * dx - s * dz) * k, dy * k, (s * dx + c * dz) * k
            d = yaw - prev[3]
            out_yaw = self._out[3] + (math.pi - (math.pi - d) % _TWO_PI)
            c, s = math.cos(out_yaw), math.sin(out_yaw)
            out_x = self._out[0] + (c * vx + s * vz)
            out_y = self._out[1] + vy
            out_z = self._out[2] + (c * vz - s * vx)
            self._out = (out_x, out_y, out_z, out_yaw)
        # Root rotation: heading removed (yaw_mul(−yaw)), then the output heading put back.
        c, s = math.cos(-0.5 * yaw), math.sin(-0.5 * yaw)
        fw, fx, fy, fz = c * w - s * y, c * x + s * z, c * y + s * w, c * z - s * x
        c, s = math.cos(0.5 * out_yaw), math.sin(0.5 * out_yaw)
        q[0] = (c * fw - s * fy, c * fx + s * fz, c * fy + s * fw, c * fz - s * fx)
        return q, np.array((out_x, out_y, out_z))


def is_copy_baseline(model: LoadedModel | RetargetModel) -> bool:
    """True for exactly the ``copy`` / ``copy-scaled`` classes (subclasses may change them)."""
    net = model.model if isinstance(model, LoadedModel) else model
    return type(net) in (CopyModel, CopyScaledModel)


def online_retargeter(
    model: LoadedModel | RetargetModel,
    source_offsets: npt.ArrayLike,
    target_offsets: npt.ArrayLike,
) -> OnlineStep:
    """The live network step for ``model``: the numpy twins for the copy baselines, the
    residual model and PMnet (pipeline.fast_residual, pipeline.fast_pmnet), else
    :class:`OnlineRetargeter` (torch)."""
    from robot_retarget.nn.models.pmnet import PMnet
    from robot_retarget.nn.models.residual import ResidualRetargeter
    from robot_retarget.pipeline.fast_pmnet import FastPMnetRetargeter
    from robot_retarget.pipeline.fast_residual import FastResidualRetargeter

    net = model.model if isinstance(model, LoadedModel) else model
    if type(net) is ResidualRetargeter:
        return FastResidualRetargeter(net, source_offsets, target_offsets)
    if type(net) is PMnet and net.causal_movement:
        return FastPMnetRetargeter(net, source_offsets, target_offsets)
    if not is_copy_baseline(model):
        return OnlineRetargeter(model, source_offsets, target_offsets)
    scale = 1.0
    if type(net) is CopyScaledModel:
        src = np.asarray(source_offsets, dtype=np.float64)
        tgt = np.asarray(target_offsets, dtype=np.float64)
        _check("source_offsets", src, (_J, 3))
        _check("target_offsets", tgt, (_J, 3))
        scale = rest_height_m(tgt) / rest_height_m(src)
    return FastCopyRetargeter(source_offsets, target_offsets, scale)
