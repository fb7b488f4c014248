"""Fixtures for the numpy rotation tests: seeded random rotations with the hard cases mixed in."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

from robot_retarget.geometry import quaternion as quat

FloatArray = npt.NDArray[np.float64]


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


@pytest.fixture
def random_quats(rng: np.random.Generator) -> FloatArray:
    """(N, 4) unit quaternions: uniform random ones plus identity, half-turns about each axis
    and about random axes, and rotations a hair away from 0 and from π."""
    uniform = quat.normalize(rng.normal(size=(500, 4)))
    axes = quat.normalize(rng.normal(size=(20, 4)))[:, 1:]
    special_angles = np.array([0.0, 1e-12, 1e-9, 1e-6, np.pi - 1e-9, np.pi - 1e-6, np.pi])
    special = quat.from_axis_angle(
        np.repeat(np.concatenate([np.eye(3), axes]), len(special_angles), axis=0),
        np.tile(special_angles, 3 + len(axes)),
    )
    both = np.concatenate([uniform, special, -special])
    return np.asarray(both, dtype=np.float64)
