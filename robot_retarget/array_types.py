"""The numpy array aliases every module uses (float64 values, int64 indices, masks; float32 where
a hot path keeps a network's own precision)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
Float32Array = npt.NDArray[np.float32]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
