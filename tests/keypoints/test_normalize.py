"""Keypoint features: the one-frame step and whole windows agree; missing points are masked."""

from __future__ import annotations

import numpy as np

from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.keypoints.normalize import KeypointNormalizer, normalize_sequences


def test_step_equals_windows_and_is_scale_invariant() -> None:
    rng = np.random.default_rng(3)
    xy = rng.uniform(100, 600, (2, 12, 17, 2))
    valid = rng.random((2, 12, 17)) > 0.2
    whole = normalize_sequences(xy, valid)
    norm = KeypointNormalizer(2)
    for t in range(12):
        np.testing.assert_allclose(norm.step(xy[:, t], valid[:, t]), whole[:, t])
    # Pixels about any origin, at any zoom: the same features (until clipping).
    moved = normalize_sequences(xy * 2.0 + 37.0, valid)
    np.testing.assert_allclose(moved, whole, atol=1e-12)


def test_missing_points_are_zero_with_a_zero_flag() -> None:
    xy = np.full((1, 1, 17, 2), 300.0)
    xy[..., 0] += np.arange(17) * 5
    xy[..., 1] += np.arange(17) * 20
    valid = np.ones((1, 1, 17), dtype=bool)
    valid[0, 0, Coco.left_wrist] = False
    xy[0, 0, Coco.left_wrist] = np.nan
    f = normalize_sequences(xy, valid).reshape(17, 3)
    assert f[Coco.left_wrist].tolist() == [0.0, 0.0, 0.0]
    assert np.isfinite(f).all()
    assert f[Coco.nose, 2] == 1.0
    # The centre is the mid-hip point: the hips sit symmetric about 0 in x.
    assert abs(f[Coco.left_hip, 0] + f[Coco.right_hip, 0]) < 1e-12


def test_nobody_in_view_gives_all_zero_features() -> None:
    f = normalize_sequences(np.full((1, 3, 17, 2), np.nan), np.zeros((1, 3, 17), dtype=bool))
    assert (f == 0.0).all()
