"""The merged position/velocity box and its projection."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.optimize.limits import box_violation, project_sequence, velocity_box

LOWER = np.array([-1.0, -2.0, 0.0])
UPPER = np.array([1.0, 0.5, 2.0])
STEP = np.array([0.1, 0.05, 0.3])

q3 = st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3).map(np.array)


@settings(max_examples=200)
@given(q_prev=q3)
def test_box_is_never_empty_and_never_asks_for_a_jump(q_prev: np.ndarray) -> None:
    lo, hi = velocity_box(q_prev, LOWER, UPPER, STEP)
    assert np.all(lo <= hi)
    assert np.all(np.abs(lo - q_prev) <= STEP + 1e-15)
    assert np.all(np.abs(hi - q_prev) <= STEP + 1e-15)
    inside = (q_prev >= LOWER) & (q_prev <= UPPER)
    assert np.all((lo >= LOWER)[inside])
    assert np.all((hi <= UPPER)[inside])


@settings(max_examples=200)
@given(q_prev=q3)
def test_outside_the_limits_the_box_moves_toward_them(q_prev: np.ndarray) -> None:
    lo, hi = velocity_box(q_prev, LOWER, UPPER, STEP)
    dist_before = np.maximum(np.maximum(q_prev - UPPER, LOWER - q_prev), 0.0)
    for q in (lo, hi):
        dist = np.maximum(np.maximum(q - UPPER, LOWER - q), 0.0)
        assert np.all(dist <= np.maximum(dist_before - STEP, 0.0) + 1e-12)


@settings(max_examples=100)
@given(
    start=q3,
    frames=st.lists(q3, min_size=1, max_size=6),
)
def test_projected_sequence_respects_every_box(start: np.ndarray, frames: list[np.ndarray]) -> None:
    out = project_sequence(np.stack(frames), start, LOWER, UPPER, STEP)
    prev = start
    for q in out:
        lo, hi = velocity_box(prev, LOWER, UPPER, STEP)
        assert box_violation(q, lo, hi) == 0.0
        prev = q


def test_box_violation() -> None:
    assert box_violation(np.array([0.0, 3.0]), np.zeros(2), np.ones(2)) == 2.0
    assert box_violation(np.array([0.5, 0.5]), np.zeros(2), np.ones(2)) == 0.0
