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
