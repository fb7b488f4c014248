"""Playback clock: always a valid frame, advances only when playing, loops."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_retarget.viewer.timeline import Timeline


@given(
    st.integers(1, 500),
    st.floats(1.0, 500.0),
    st.floats(0.01, 4.0),
    st.lists(st.floats(0.0, 10.0), max_size=20),
)
def test_frame_stays_in_the_clip(n: int, fps: float, speed: float, steps: list[float]) -> None:
    timeline = Timeline(n, fps, speed=speed)
    for wall in steps:
        assert 0 <= timeline.advance(wall) < n


def test_playing_advances_at_speed_and_wraps() -> None:
    timeline = Timeline(100, 50.0, speed=0.5)
    assert timeline.advance(1.0) == 25
    assert timeline.advance(3.0) == 0  # 25 + 75 frames = one full loop
    timeline.speed = 2.0
    assert timeline.advance(0.1) == 10


def test_paused_does_not_move_and_seek_clamps() -> None:
    timeline = Timeline(10, 10.0, t0=-0.5, playing=False)
    assert timeline.advance(5.0) == 0
    assert timeline.seek(99) == 9
    assert timeline.time_s == pytest.approx(0.4)
    assert timeline.seek(-3) == 0


def test_bad_timelines_are_refused() -> None:
    with pytest.raises(ValueError, match="at least one frame"):
        Timeline(0, 10.0)
    with pytest.raises(ValueError, match="fps must be positive"):
        Timeline(5, 0.0)
