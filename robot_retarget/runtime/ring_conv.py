"""A causal temporal convolution stepped one frame at a time (the numpy runtimes' live path).

The layer keeps a ring of its last (k − 1)·d + 1 inputs (k taps, dilation d). The ring starts
filled with the first frame, as the torch layers' left padding repeats it, so stepping a
clip frame by frame gives the clip path's numbers.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.runtime.frame import F32Array

Conv = tuple[FloatArray, FloatArray]  # kernel (out, in, k), bias (out,)


def leaky_relu(x: npt.NDArray[np.floating], slope: float = 0.2) -> npt.NDArray[np.floating]:
    """Leaky ReLU (slope below one), as between the torch models' convolutions."""
    return np.maximum(x, slope * x)


def f32_conv(conv: Conv) -> tuple[F32Array, F32Array]:
    return np.asarray(conv[0], dtype=np.float32), np.asarray(conv[1], dtype=np.float32)


class RingConv:
    """One causal temporal convolution stepped online: a ring of its last (k − 1)·d + 1
    inputs, so a frame costs one matrix–vector product whatever the kernel's reach."""

    def __init__(self, conv: Conv, dilation: int) -> None:
        kern, bias = f32_conv(conv)
        out_ch, in_ch, k = kern.shape
        self.k = k
        self.dilation = dilation
        self.size = (k - 1) * dilation + 1
        # (out, k·in): tap i (oldest first) in columns i·in … (i + 1)·in.
        self.kernel = np.ascontiguousarray(kern.transpose(0, 2, 1).reshape(out_ch, k * in_ch))
        self.bias = bias
        # Every input is written twice, at p and p + size, so the last ``size`` inputs are
        # always one contiguous slice and the taps a strided view of it (no gather).
        self.ring = np.zeros((2 * self.size, in_ch), dtype=np.float32)
        self.pos = 0
        self.started = False

    def reset(self) -> None:
        self.started = False

    def step(self, x: F32Array) -> F32Array:
        if self.k == 1:
            out: F32Array = self.kernel @ x + self.bias
            return out
        n = self.size
        if not self.started:
            self.ring[:] = x  # the left padding: copies of the first frame
            self.pos = 0
            self.started = True
        p = self.pos = (self.pos + 1) % n
        self.ring[p] = x
        self.ring[p + n] = x
        # Taps t − (k − 1)·d … t, oldest first (the kernel's order): rows p + 1 … p + n.
        taps = self.ring[p + 1 : p + n + 1 : self.dilation]
        out = self.kernel @ taps.reshape(-1) + self.bias
        return out
