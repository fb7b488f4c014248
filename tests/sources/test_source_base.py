from __future__ import annotations

import threading

import numpy as np
import pytest

from robot_retarget.sources.base import (
    DROP_REASONS,
    FrameQueue,
    SequenceFilter,
    SourceFrame,
    SourceStats,
)


def _frame(seq: int) -> SourceFrame:
    return SourceFrame(np.zeros((22, 4)), np.zeros(3), seq * 0.01, seq, 0.0)


def test_queue_is_bounded_and_thread_safe() -> None:
    stats = SourceStats()
    q = FrameQueue(stats, max_frames=100)

    def fill(start: int) -> None:
        for k in range(start, start + 500):
            q.put(_frame(k))

    threads = [threading.Thread(target=fill, args=(k * 1000,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(q.drain()) == 100
    assert stats.dropped["queue_full"] == 1900
    assert q.drain() == []
    with pytest.raises(ValueError, match="max_frames"):
        FrameQueue(stats, max_frames=0)


def test_sequence_filter_reasons() -> None:
    stats = SourceStats()
    f = SequenceFilter(stats)
    assert f.accept(5, 1.0)
    assert not f.accept(5, 1.1)  # duplicate sequence number
    assert not f.accept(4, 1.2)  # older sequence number
    assert not f.accept(6, 1.0)  # timestamp not increasing
    assert f.accept(7, 1.3)
    assert f.accept(0, 0.0)  # sequence 0: the sender restarted
    assert stats.dropped["duplicate"] == 1
    assert stats.dropped["out_of_order"] == 2
    assert set(stats.dropped) == set(DROP_REASONS)


def test_a_sender_restarting_its_sequence_and_clock_is_accepted() -> None:
    stats = SourceStats()
    f = SequenceFilter(stats)
    for k in range(100, 110):
        assert f.accept(k, 50.0 + k / 60)
    assert f.accept(3, 0.05)  # seq back to a small number, not 0, and the clock restarted
    assert f.accept(4, 0.07)
    assert f.restarts == 1
    assert not f.accept(2, 0.03)  # an old datagram of the new stream: still out of order
    assert stats.dropped["out_of_order"] == 1
    assert stats.warnings == []


def test_a_late_datagram_is_not_a_restart() -> None:
    stats = SourceStats()
    f = SequenceFilter(stats)
    assert f.accept(10, 1.0)
    assert not f.accept(9, 0.98)  # a few frames late: both went back, but by < 0.5 s
    assert f.restarts == 0
    assert stats.dropped["out_of_order"] == 1


def test_a_run_of_out_of_order_drops_warns_live() -> None:
    stats = SourceStats()
    live: list[str] = []
    stats.on_warning = live.append
    f = SequenceFilter(stats, warn_after=30)
    assert f.accept(5000, 100.0)
    # The sender restarted its sequence numbers but not its clock: every packet goes back in
    # sequence, forward in time. Dropped (the rule), but never silently.
    for k in range(1, 30):
        assert not f.accept(k, 100.0 + k / 60)
    assert live == []
    assert not f.accept(30, 100.5)
    assert len(live) == 1
    assert "30 packets in a row dropped as out of order" in live[0]
    assert "restart its timestamps" in live[0]
    for k in range(31, 330):
        f.accept(k, 100.5 + k / 60)
    assert len(live) == 1
    f.accept(330, 106.0)
    assert len(live) == 2  # again every 10 × warn_after drops while it lasts
    assert "330 packets in a row" in live[1]
    assert stats.warnings == live
    assert "2 warning(s), the last: source: 330 packets" in stats.summary()
    assert f.accept(5001, 107.0)  # an accepted frame ends the run
    for k in range(29):
        f.accept(k + 1, 107.0 + k)
    assert len(live) == 2
    with pytest.raises(ValueError, match="warn_after"):
        SequenceFilter(stats, warn_after=0)


def test_two_senders_on_one_port_are_not_taken_for_restarts() -> None:
    """Two programs sending to one port, each with its own sequence and clock: every switch
    between them passed as a restart, and the robot played both performers, packet by packet.
    Now the stream followed is kept and the other's packets are dropped, with a warning."""
    stats = SourceStats()
    f = SequenceFilter(stats)
    followed: list[str] = []
    for k in range(60):
        for name, seq, t in (("a", k, k / 60), ("b", 100_000 + k, 1000.0 + k / 60)):
            if f.accept(seq, t):
                followed.append(name)
    assert followed.count("b") <= 1  # the first of b's may pass as a jump of a's stream
    assert followed.count("a") == 60
    assert stats.dropped["second_sender"] >= 58
    assert any("second sender on this port" in w for w in stats.warnings)


def test_a_restart_leaves_its_old_stream_behind_without_a_warning() -> None:
    stats = SourceStats()
    f = SequenceFilter(stats)
    for k in range(100, 160):
        assert f.accept(k, 50.0 + k / 60)
    for k in range(0, 60):  # restarted: seq and clock from 0
        assert f.accept(k, k / 60)
    assert f.restarts == 1
    assert stats.warnings == []
