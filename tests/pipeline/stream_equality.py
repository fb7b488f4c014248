"""Shared check of the numpy twins: the live step equals the torch OnlineRetargeter."""

from __future__ import annotations

import numpy as np

from robot_retarget.nn.inference import LoadedModel, OnlineRetargeter
from robot_retarget.runtime.loader import online_retargeter

HALF_TURN_MARGIN_RAD = 1e-3


def clear_of_half_turns(quats: np.ndarray) -> bool:
    """True when no frame-to-frame change of the root's heading (the turning rate the models
    read, wrapped to (−π, π]) lies within HALF_TURN_MARGIN_RAD of ±π. A turn of half a circle
    in one frame has two equally good signs, and the torch model (float32) and its twin
    (float64) may round it to opposite ones: there the streams are both right and differ."""
    w, x, y, z = (quats[:, 0, k] for k in range(4))
    yaw = np.arctan2(-2.0 * (x * z - w * y), 1.0 - 2.0 * (y * y + z * z))
    turn = np.pi - np.mod(np.pi - np.diff(yaw), 2.0 * np.pi)
    return bool(np.all(np.abs(turn) < np.pi - HALF_TURN_MARGIN_RAD))


def assert_same_stream(
    model: LoadedModel,
    src: np.ndarray,
    tgt: np.ndarray,
    quats: np.ndarray,
    root: np.ndarray,
    twin: type,
    atol: float,
) -> None:
    """Both paths over the same frames, twice (reset in between), output for output; the
    pipeline must pick the numpy ``twin`` for ``model``. Quaternions are compared up to sign."""
    torch_step = OnlineRetargeter(model, src, tgt)
    fast = online_retargeter(model, src, tgt)
    assert isinstance(fast, twin)
    for _ in range(2):
        torch_step.reset()
        fast.reset()
        for t in range(len(quats)):
            want_q, want_p = torch_step.step(quats[t], root[t])
            got_q, got_p = fast.step(quats[t], root[t])
            same_sign = np.where(np.sum(got_q * want_q, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
            np.testing.assert_allclose(got_q * same_sign, want_q, rtol=0, atol=atol)
            np.testing.assert_allclose(got_p, want_p, rtol=0, atol=atol)
