"""Length units: detection from standing height, and names."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import MotionFormatError
from robot_retarget.motion.units import CMU_UNIT_M, UNIT_SCALES_M, detect_unit, unit_scale_m


@pytest.mark.parametrize(
    ("height", "unit"),
    [(1.75, "m"), (172.0, "cm"), (1690.0, "mm"), (68.0, "inch"), (26.0, "cmu"), (33.0, "cmu")],
)
def test_detects_typical_heights(height: float, unit: str) -> None:
    assert detect_unit(height) == unit


@given(unit=st.sampled_from(sorted(UNIT_SCALES_M)), height_m=st.floats(1.4, 2.0))
@settings(max_examples=50)
def test_any_adult_height_in_any_unit_is_recognised(unit: str, height_m: float) -> None:
    assert detect_unit(height_m / UNIT_SCALES_M[unit]) == unit


def test_cmu_unit_value() -> None:
    assert pytest.approx(0.0564, abs=1e-4) == CMU_UNIT_M
    assert unit_scale_m("cmu") == CMU_UNIT_M


def test_errors() -> None:
    with pytest.raises(MotionFormatError, match="unknown length unit"):
        unit_scale_m("parsec")
    with pytest.raises(MotionFormatError, match="pass the unit"):
        detect_unit(0.0)
