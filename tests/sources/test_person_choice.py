"""The rule that picks one person among several (robot_retarget.sources.keypoints.person_choice)."""

from __future__ import annotations

import numpy as np

from robot_retarget.sources.keypoints.person_choice import PersonTracker


def _person(cx: float, cy: float, size: float) -> tuple[np.ndarray, np.ndarray]:
    xy = np.array([[cx - size, cy - size], [cx + size, cy + size], [cx, cy]])
    return xy, np.ones(3, dtype=bool)


def test_largest_first_then_nearest() -> None:
    tr = PersonTracker()
    assert tr.choose([_person(100, 100, 10), _person(500, 300, 50)]) == 1
    # The other person grows larger, but the followed one is still nearest its last centre.
    assert tr.choose([_person(110, 100, 200), _person(505, 300, 50)]) == 1
    assert tr.choose([_person(510, 305, 50), _person(100, 100, 300)]) == 0


def test_jump_means_nobody_then_reacquire() -> None:
    tr = PersonTracker(reacquire_frames=3)
    assert tr.choose([_person(500, 300, 50)]) == 0
    # The followed person vanished; someone else far away is not taken for them.
    assert tr.choose([_person(100, 100, 20)]) is None
    assert tr.choose([_person(100, 100, 20)]) is None
    assert tr.choose([_person(100, 100, 20)]) is None  # third miss: reacquire next frame
    assert tr.choose([_person(100, 100, 20)]) == 0


def test_nobody_and_single_points() -> None:
    tr = PersonTracker()
    assert tr.choose([]) is None
    one_point = (np.array([[1.0, 2.0], [3.0, 4.0]]), np.array([True, False]))
    assert tr.choose([one_point]) is None  # fewer than two visible points: no box


def test_one_wild_point_does_not_lose_the_person() -> None:
    """A glitch at full confidence (one wrist across the image) in a 17-point body: the
    followed person is kept, where a plain bounding box's centre would jump past the gate."""
    rng = np.random.default_rng(0)
    body = np.column_stack([rng.uniform(560, 640, 17), rng.uniform(200, 500, 17)])
    seen = np.ones(17, dtype=bool)
    tr = PersonTracker()
    assert tr.choose([(body, seen)]) == 0
    glitch = body.copy()
    glitch[9] = (1270.0, 10.0)
    for _ in range(3):
        assert tr.choose([(glitch, seen)]) == 0
    assert tr.choose([(body + 5.0, seen)]) == 0
