"""Fixtures for the metric tests: a walking motion on the default skeleton, flat skeletons."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pytest

from robot_retarget.geometry import quaternion as quat
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

FloatArray = npt.NDArray[np.float64]


def walking_rotations(frames: int, seed: int = 0) -> tuple[FloatArray, FloatArray]:
    """Smooth random local rotations (T, 22, 4) and a root path (T, 3), metres."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None, None] / 30.0
    amp = rng.uniform(0.1, 0.6, size=(1, 22, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(1, 22, 3))
    q = quat.from_rotation_vector(amp * np.sin(2 * np.pi * t + phase))
    root = np.stack([0.2 * t[:, 0, 0], 0.9 + 0.0 * t[:, 0, 0], 1.1 * t[:, 0, 0]], axis=-1)
    return q, root


@pytest.fixture
def walking() -> Callable[[int], tuple[FloatArray, FloatArray]]:
    """walking_rotations as a fixture: frames → (local_quats, root_pos)."""
    return walking_rotations


@pytest.fixture
def skeleton() -> Skeleton:
    return default_canonical_skeleton()


@pytest.fixture
def flat_skeleton() -> Skeleton:
    """Default skeleton with every bone in the XY plane (toes pointing down)."""
    offs = default_canonical_skeleton().offsets.copy()
    offs[:, 2] = 0.0
    return default_canonical_skeleton().with_offsets(offs)


@pytest.fixture
def motion(skeleton: Skeleton) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(local_quats, root_pos, positions) of 40 frames."""
    q, root = walking_rotations(40)
    return q, root, forward_kinematics(skeleton, q, root)[0]
