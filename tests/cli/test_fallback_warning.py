"""The warning convert and stream print when the solver failed on many frames."""

from __future__ import annotations

from robot_retarget.cli.fallback_warning import fallback_warning


def test_many_fallbacks_earn_a_warning_that_says_what_to_check() -> None:
    assert fallback_warning(0, 208) is None
    assert fallback_warning(20, 208) is None  # under a tenth: the optimizer's business
    assert fallback_warning(0, 0) is None
    text = fallback_warning(189, 208)
    assert text is not None
    assert "189 of 208 frames" in text
    assert "forward_axis" in text
