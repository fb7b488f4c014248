"""Foot contacts and foot skate: planted feet, sliding feet, lifted feet."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.evaluation.foot_contact import (
    FOOT_JOINTS,
    foot_contacts,
    foot_skate,
    horizontal_speed,
)


def _standing(frames: int = 30) -> np.ndarray:
    pos = np.zeros((frames, 22, 3))
    pos[:, :, 1] = 0.5
    pos[:, list(FOOT_JOINTS), 1] = 0.05
    return pos


def test_planted_feet_are_in_contact_and_do_not_skate() -> None:
    pos = _standing()
    contacts = foot_contacts(pos, 30.0, 0.9)
    assert contacts.shape == (30, 4)
    assert contacts.all()
    assert foot_skate(pos, contacts, 30.0, 0.9) == 0.0


def test_sliding_target_skates_at_its_speed() -> None:
    src = _standing()
    contacts = foot_contacts(src, 30.0, 0.9)
    tgt = _standing()
    speed_m_s = 0.45
    tgt[:, :, 0] += speed_m_s * np.arange(30)[:, None] / 30.0
    assert foot_skate(tgt, contacts, 30.0, 0.5) == pytest.approx(speed_m_s / 0.5)


def test_moving_or_lifted_feet_are_not_in_contact() -> None:
    pos = _standing()
    pos[:, FOOT_JOINTS[0], 0] = np.arange(30) * 0.1  # 3 m/s: swinging
    pos[10:20, FOOT_JOINTS[2], 1] = 0.5  # lifted 45 cm
    contacts = foot_contacts(pos, 30.0, 0.9)
    assert not contacts[:, 0].any()
    assert not contacts[10:20, 2].any()
    assert contacts[:10, 2].all()
    assert contacts[:, [1, 3]].all()


def test_no_contact_gives_nan() -> None:
    pos = _standing()
    assert np.isnan(foot_skate(pos, np.zeros((30, 4), dtype=bool), 30.0, 0.9))


def test_horizontal_speed_ignores_vertical_motion() -> None:
    p = np.zeros((3, 1, 3))
    p[:, 0, 1] = [0.0, 1.0, 2.0]
    p[:, 0, 2] = [0.0, 0.1, 0.2]
    np.testing.assert_allclose(horizontal_speed(p, 10.0), 1.0)
    with pytest.raises(ValueError, match="must be"):
        foot_skate(np.zeros((3, 22, 3)), np.ones((2, 4), dtype=bool), 10.0, 1.0)
