"""The box-constrained QP behind the GMR-style IK: optimal (KKT) for any convex problem."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.evaluation.robot.box_qp import box_qp


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 20), scale=st.floats(0.01, 100.0))
def test_solution_satisfies_kkt(seed: int, n: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    h = a @ a.T + 1e-3 * np.eye(n)
    c = rng.normal(size=n) * scale
    lo = -rng.uniform(0.0, 1.0, n)
    hi = rng.uniform(0.0, 1.0, n)
    lo[rng.random(n) < 0.1] = 0.0  # some variables pinned on one side
    x = box_qp(h, c, lo, hi)
    assert np.all(x >= lo)
    assert np.all(x <= hi)
    g = h @ x + c
    tol = 1e-8 * (1.0 + np.abs(c).max() + np.abs(h).max())
    inside = (x > lo + 1e-12) & (x < hi - 1e-12)
    assert np.all(np.abs(g[inside]) <= tol)  # stationary in the free directions
    assert np.all(g[(x <= lo) & (lo < hi)] >= -tol)  # at a lower bound: pushing down
    assert np.all(g[(x >= hi) & (lo < hi)] <= tol)  # at an upper bound: pushing up


def test_unconstrained_minimum_inside_the_box() -> None:
    h = np.diag([2.0, 4.0])
    c = np.array([-1.0, 2.0])
    np.testing.assert_allclose(box_qp(h, c, -np.ones(2), np.ones(2)), [0.5, -0.5])


def test_empty_box_is_an_error() -> None:
    with pytest.raises(ValueError, match="exceeds"):
        box_qp(np.eye(1), np.zeros(1), np.ones(1), np.zeros(1))
