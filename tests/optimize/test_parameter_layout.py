"""ParameterLayout: named blocks tile the vector exactly once, whatever the window."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_retarget.optimize.parameter_layout import Parameter, ParameterLayout

blocks = st.lists(st.tuples(st.integers(0, 5), st.booleans()), min_size=1, max_size=8)


@given(spec=blocks, window=st.integers(1, 6))
def test_blocks_tile_the_vector_once(spec: list[tuple[int, bool]], window: int) -> None:
    lay = ParameterLayout([Parameter(f"b{i}", n, s) for i, (n, s) in enumerate(spec)])
    covered = np.zeros(lay.size(window), dtype=int)
    for i, (n, shared) in enumerate(spec):
        name = f"b{i}"
        if shared:
            covered[lay.shared(name)] += 1
            assert lay.shared(name).stop - lay.shared(name).start == n
        else:
            for t in range(window):
                covered[lay.frame(t, name)] += 1
    assert np.all(covered == 1)


def test_bad_declarations_are_rejected() -> None:
    with pytest.raises(ValueError, match="twice"):
        ParameterLayout([Parameter("a", 1), Parameter("a", 2, shared=True)])
    with pytest.raises(ValueError, match="negative"):
        ParameterLayout([Parameter("a", -1)])
