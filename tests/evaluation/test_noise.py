"""Denoising-protocol corruption: magnitude, zeros, untouched root rotation."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robot_retarget.evaluation.noise import corrupt
from robot_retarget.geometry import quaternion as quat

Walking = Callable[[int], tuple[np.ndarray, np.ndarray]]


def test_no_noise_changes_nothing(walking: Walking) -> None:
    q, root = walking(10)
    nq, nr = corrupt(q, root, 1.7, np.random.default_rng(0), sigma_frac=0.0, zero_prob=0.0)
    np.testing.assert_allclose(np.abs(np.sum(nq * q, axis=-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(nr, root)


def test_noise_magnitude_and_zeros(walking: Walking) -> None:
    q, root = walking(400)
    nq, nr = corrupt(q, root, 2.0, np.random.default_rng(1), sigma_frac=0.01, zero_prob=0.0)
    assert abs(np.std(nr - root) - 0.02) < 0.002  # σ = 0.01 × height
    np.testing.assert_allclose(nq[:, 0], q[:, 0])  # root rotation keeps the heading clean
    angles = quat.angle_between(nq[:, 1:], q[:, 1:])
    assert 0.05 < np.mean(angles) < 0.15  # 3-D Gaussian of σ 0.06 rad: mean angle ≈ 0.096
    zq, _ = corrupt(q, root, 2.0, np.random.default_rng(2), sigma_frac=0.0, zero_prob=1.0)
    np.testing.assert_allclose(zq[:, 1:], quat.identity((400, 21)), atol=1e-12)
