"""Fixtures for the skeleton tests: the canonical skeleton and seeded random trees and poses."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.skeleton import Skeleton, default_canonical_skeleton


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


@pytest.fixture
def canonical() -> Skeleton:
    return default_canonical_skeleton()


@pytest.fixture
def chain() -> Skeleton:
    """Three joints in a line along +x, 1 m apart: easy to reason about by hand."""
    return Skeleton(("root", "a", "b"), (-1, 0, 1), np.array([[0.0, 0, 0], [1, 0, 0], [1, 0, 0]]))
