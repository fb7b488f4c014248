"""The online solve's compiled check equals its numpy statement, non-finite values included."""

from __future__ import annotations

from types import SimpleNamespace
from typing import cast

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.optimize.online_check import OnlineCheck
from robot_retarget.optimize.solver import BufferedSolver

_VALUES = st.one_of(st.floats(-3.0, 3.0), st.sampled_from([np.nan, np.inf, -np.inf]), st.just(0.0))


def _solver(nx: int, ng: int) -> SimpleNamespace:
    return SimpleNamespace(
        x=np.zeros(nx), g=np.zeros(ng), lbg=np.zeros(ng), ubg=np.zeros(ng),
        lbx=np.zeros(nx), ubx=np.zeros(nx),
    )  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(data=st.data(), nx=st.sampled_from([1, 3, 6]), ng=st.sampled_from([0, 2]), jit=st.booleans())
def test_the_check_is_its_numpy_statement(data: st.DataObject, nx: int, ng: int, jit: bool) -> None:
    s = _solver(nx, ng)
    check = OnlineCheck(cast(BufferedSolver, s), jit=jit)
    s.x[:] = data.draw(st.lists(_VALUES, min_size=nx, max_size=nx))
    s.g[:] = data.draw(st.lists(_VALUES, min_size=ng, max_size=ng))
    s.lbg[:] = data.draw(st.lists(st.floats(-2.0, 0.0), min_size=ng, max_size=ng))
    s.ubg[:] = s.lbg + data.draw(st.lists(st.floats(0.0, 2.0), min_size=ng, max_size=ng))
    s.lbx[:] = data.draw(st.lists(st.floats(-2.0, 0.0), min_size=nx, max_size=nx))
    s.ubx[:] = s.lbx + data.draw(st.lists(st.floats(0.0, 2.0), min_size=nx, max_size=nx))
    finite, violation = check()
    assert finite == bool(np.isfinite(s.x).all() and np.isfinite(s.g).all())
    if finite:
        below, above = np.max(s.lbg - s.g, initial=0.0), np.max(s.g - s.ubg, initial=0.0)
        assert violation == max(float(below), float(above))
        np.testing.assert_array_equal(check.q, np.minimum(np.maximum(s.x, s.lbx), s.ubx))
