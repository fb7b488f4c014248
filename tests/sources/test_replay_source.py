from __future__ import annotations

import itertools

import pytest

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.sources.replay import ReplaySource


def test_frames_arrive_when_due(motion: HumanMotion) -> None:
    src = ReplaySource(motion)
    src.start()
    first = src.poll(100.0)
    assert [f.seq for f in first] == [0]
    assert src.poll(100.0) == []
    batch = src.poll(100.0 + 0.1)  # 30 fps: frames 1..3 are due
    assert [f.seq for f in batch] == [1, 2, 3]
    assert batch[-1].t_s == pytest.approx(0.1)
    assert batch[-1].recv_s == pytest.approx(100.1)
    assert not src.finished
    rest = src.poll(200.0)
    assert rest[-1].seq == motion.num_frames - 1
    assert src.finished
    assert src.stats.accepted == motion.num_frames


def test_loop_keeps_timestamps_increasing(motion: HumanMotion) -> None:
    src = ReplaySource(motion, loop=True, speed=2.0)
    src.start()
    src.poll(0.0)
    frames = src.poll(motion.duration_s)  # 2× speed: almost two loops
    ts = [f.t_s for f in frames]
    assert all(b > a for a, b in itertools.pairwise(ts))
    assert len(frames) > motion.num_frames
    assert not src.finished
    assert src.nominal_fps == pytest.approx(2 * motion.fps)


def test_bad_speed_is_refused(motion: HumanMotion) -> None:
    with pytest.raises(ValueError, match="speed"):
        ReplaySource(motion, speed=0.0)


def test_not_started_gives_nothing(motion: HumanMotion) -> None:
    assert ReplaySource(motion).poll(5.0) == []
