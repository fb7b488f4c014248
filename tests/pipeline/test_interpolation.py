from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.geometry import quaternion as quat
from robot_retarget.pipeline.interpolation import FrameInterpolator
from robot_retarget.sources.base import SourceFrame


def _frame(seq: int, t_s: float, recv_s: float, angle: float) -> SourceFrame:
    q = np.broadcast_to(quat.from_axis_angle([0.0, 1.0, 0.0], angle), (22, 4)).copy()
    return SourceFrame(q, np.array([angle, 0.0, 0.0]), t_s, seq, recv_s)


def test_slerps_between_frames_after_the_playout_delay() -> None:
    it = FrameInterpolator(delay_s=0.1)
    assert it.sample(0.0) is None
    it.push(_frame(0, 0.0, 10.0, 0.0), 10.0)
    it.push(_frame(1, 0.1, 10.1, 1.0), 10.1)
    s = it.sample(10.15)  # play time 0.05: halfway
    assert s is not None
    assert not s.late
    assert s.play_t_s == pytest.approx(0.05)
    np.testing.assert_allclose(quat.angle_between(s.local_quats[3], _frame(0, 0, 0, 0.5)
                                                  .local_quats[3]), 0.0, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(s.root_pos[0], 0.5)
    assert s.newest.seq == 1


def test_holds_the_newest_frame_when_late() -> None:
    it = FrameInterpolator(delay_s=0.02)
    it.push(_frame(0, 0.0, 1.0, 0.0), 1.0)
    it.push(_frame(1, 0.02, 1.02, 0.3), 1.02)
    s = it.sample(1.5)
    assert s is not None
    assert s.late
    np.testing.assert_allclose(s.root_pos[0], 0.3)
    it.push(_frame(2, 0.04, 1.6, 0.4), 1.6)  # arrived after its play time
    assert it.late_frames == 1


def test_a_sender_faster_than_the_loop_is_not_late() -> None:
    """120 fps frames read at a 50 Hz loop's polls arrive in bunches, most of them behind the
    play time by then, but a newer one in the same poll covers every tick: none is late."""
    it = FrameInterpolator(delay_s=1 / 120)
    sent = 0
    for tick in range(1, 100):
        now = tick * 0.02
        while sent / 120 <= now:
            it.push(_frame(sent, sent / 120, now, 0.0), now)
            sent += 1
        s = it.sample(now)
        assert s is not None
        assert not s.late
    assert it.late_frames == 0


def test_offset_follows_the_fastest_transit() -> None:
    it = FrameInterpolator(delay_s=0.0)
    it.push(_frame(0, 0.0, 5.05, 0.0), 5.05)  # slow first packet
    it.push(_frame(1, 0.1, 5.10, 1.0), 5.10)  # faster one
    assert it.play_time(5.10) == pytest.approx(0.1)


def test_timestamp_going_back_is_a_restart() -> None:
    it = FrameInterpolator(delay_s=0.0)
    it.push(_frame(5, 3.0, 1.0, 0.0), 1.0)
    it.push(_frame(0, 0.0, 2.0, 1.0), 2.0)
    assert it.restarts == 1
    s = it.sample(2.0)
    assert s is not None
    assert s.newest.seq == 0


def test_before_the_first_frame_plays_the_oldest() -> None:
    it = FrameInterpolator(delay_s=0.5)
    it.push(_frame(0, 0.0, 0.0, 0.2), 0.0)
    it.push(_frame(1, 0.1, 0.1, 0.4), 0.1)
    s = it.sample(0.1)
    assert s is not None
    np.testing.assert_allclose(s.root_pos[0], 0.2)


def test_negative_delay_is_refused() -> None:
    with pytest.raises(ValueError, match="delay"):
        FrameInterpolator(delay_s=-1.0)


def test_delay_adapts_to_the_measured_input_period() -> None:
    it = FrameInterpolator(delay_s=1 / 60, adapt_periods=1.0)  # announced 60 fps
    for k in range(60):  # the sender really sends 20 fps
        it.push(_frame(k, k * 0.05, 1.0 + k * 0.05, 0.0), 1.0 + k * 0.05)
    assert it.delay_s == pytest.approx(0.05, rel=0.01)


def test_a_paused_sender_clock_is_followed() -> None:
    it = FrameInterpolator(delay_s=0.0)
    it.push(_frame(0, 0.0, 0.0, 0.0), 0.0)
    it.push(_frame(1, 0.1, 2.0, 0.5), 2.0)  # sender clock stood still for ~1.9 s
    assert it.resyncs == 1
    s = it.sample(2.0)
    assert s is not None
    assert not s.late
    np.testing.assert_allclose(s.root_pos[0], 0.5)
