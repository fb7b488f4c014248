"""The constant tables equal the quaternion functions they replace."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.geometry.quaternion_tables import matrix_table, product_table, rotation_table

QUATS = arrays(np.float64, (5, 4), elements=st.floats(-2.0, 2.0))


def _outer(q: np.ndarray) -> np.ndarray:
    return (q[:, :, None] * q[:, None, :]).reshape(-1, 16)


@settings(max_examples=50)
@given(QUATS, QUATS)
def test_product_table_is_the_hamilton_product(a: np.ndarray, b: np.ndarray) -> None:
    outer = (a[:, :, None] * b[:, None, :]).reshape(-1, 16)
    np.testing.assert_allclose(outer @ product_table(), quat.mul(a, b), atol=1e-12)


@settings(max_examples=50)
@given(QUATS)
def test_rotation_and_matrix_tables(q: np.ndarray) -> None:
    rot = (_outer(q) @ rotation_table()).reshape(-1, 3, 3) + np.eye(3)
    np.testing.assert_allclose(rot @ np.ones(3), quat.rotate(q, np.ones((5, 3))), atol=1e-9)
    unit = quat.normalize(q + np.array([1e-3, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(
        (_outer(unit) @ matrix_table()).reshape(-1, 3, 3), quat.to_matrix(unit), atol=1e-12
    )


def test_tables_are_read_only() -> None:
    for table in (product_table(), rotation_table(), matrix_table()):
        assert not table.flags.writeable
