"""The rule that picks one person among several (robot_retarget.sources.keypoints.person_choice)."""

from __future__ import annotations

import warnings

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


# A standing person facing the camera, COCO-17 order, pixels (about 430 px tall).
_STANDING = np.array(
    [
        [320, 100], [328, 92], [312, 92], [338, 98], [302, 98],  # nose, eyes, ears
        [370, 160], [270, 160], [380, 240], [260, 240], [385, 310], [255, 310],  # arms
        [352, 300], [288, 300], [355, 410], [285, 410], [358, 520], [282, 520],  # legs
    ],
    dtype=float,
)  # fmt: skip


def test_a_body_that_comes_into_view_below_the_head_is_the_same_person() -> None:
    """Head and shoulders first (a small box, its centre high), then the whole body in the
    same pixels: the centre of all the points is far below, but over the points both frames
    show the person has not moved. And the same person with a stranger beside them."""
    head = np.zeros(17, dtype=bool)
    head[:7] = True
    whole = np.ones(17, dtype=bool)
    tr = PersonTracker()
    assert tr.choose([(_STANDING, head)]) == 0
    assert [tr.choose([(_STANDING, whole)]) for _ in range(3)] == [0, 0, 0]
    tr = PersonTracker()
    stranger = (_STANDING + np.array([600.0, 200.0]), whole)
    assert tr.choose([(_STANDING, head)]) == 0
    assert tr.choose([stranger, (_STANDING, whole)]) == 1


def test_one_frame_of_points_collapsed_onto_a_pixel_does_not_lose_the_person() -> None:
    """An estimator's failure puts every point on one pixel (a box of no size) for a frame:
    the person is still followed in it and in the next (the larger box sets the reach), and
    points at 1e200 px are far away, without a numpy warning."""
    whole = np.ones(17, dtype=bool)
    tr = PersonTracker()
    assert tr.choose([(_STANDING, whole)]) == 0
    assert tr.choose([(np.full((17, 2), 330.0), whole)]) == 0
    assert tr.choose([(_STANDING, whole)]) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert tr.choose([(np.full((17, 2), 1e200), whole)]) is None
        assert tr.choose([(_STANDING, whole)]) == 0


def test_a_larger_stranger_who_hides_the_person_is_not_followed() -> None:
    """Someone near the camera (a box twice the size) steps in front of the followed person:
    nobody that frame, and the person again when they reappear, however large the stranger."""
    whole = np.ones(17, dtype=bool)
    tr = PersonTracker()
    assert tr.choose([(_STANDING, whole)]) == 0
    stranger = (2.0 * (_STANDING - 320.0) + np.array([520.0, 320.0]), whole)  # off to one side
    assert tr.choose([stranger]) is None
    assert tr.choose([stranger, (_STANDING, whole)]) == 1
