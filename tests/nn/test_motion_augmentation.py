"""Training-window augmentation: mirroring, playback speed and arm mixing keep exact 3D ground
truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.cli.train_cmd import TrainArgumentError, _motion_augmentation
from robot_retarget.nn.agnostic2d_training import TwoViewSampler
from robot_retarget.nn.dataset import Clip, MotionDataset
from robot_retarget.nn.motion_augmentation import (
    ARM_JOINTS,
    MotionAugmentation,
    augmented_window,
)
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, default_canonical_skeleton
from robot_retarget.skeleton.mirror import mirror_rotations

_J = len(CANONICAL_JOINTS)


def _clip(frames: int = 120, seed: int = 0) -> Clip:
    """A smooth synthetic motion: every joint turns at its own constant rate."""
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(_J, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angle = np.arange(frames)[:, None] * rng.uniform(0.01, 0.05, _J)[None]
    q = np.concatenate(
        [np.cos(angle / 2)[..., None], np.sin(angle / 2)[..., None] * axes[None]], axis=-1
    )
    root = np.stack([np.arange(frames) * 0.01, np.full(frames, 0.9), np.zeros(frames)], axis=-1)
    return Clip("synthetic", "99", q, root, default_canonical_skeleton().offsets, 30.0, 1.7)


def test_an_unchanged_window_is_a_slice_of_the_clip() -> None:
    clip = _clip()
    w = augmented_window(clip, 40, np.random.default_rng(3), MotionAugmentation(0.0, (1.0, 1.0)))
    start = int(w.name.split("@")[1])
    np.testing.assert_allclose(w.local_quats, clip.local_quats[start : start + 40])
    np.testing.assert_allclose(w.root_pos, clip.root_pos[start : start + 40])
    np.testing.assert_array_equal(w.offsets, clip.offsets)


def test_a_mirrored_window_is_the_mirrored_slice() -> None:
    clip = _clip()
    w = augmented_window(clip, 40, np.random.default_rng(3), MotionAugmentation(1.0, (1.0, 1.0)))
    start = int(w.name.split("@")[1])
    np.testing.assert_allclose(
        w.local_quats, mirror_rotations(clip.local_quats[start : start + 40])
    )
    np.testing.assert_allclose(w.root_pos[:, 0], -clip.root_pos[start : start + 40, 0])


@settings(max_examples=25, deadline=None)
@given(st.floats(0.5, 2.0), st.integers(0, 1000))
def test_a_faster_window_moves_faster_by_that_factor(speed: float, seed: int) -> None:
    """Constant-rate joints and a constant-velocity root: resampled at speed s, every frame
    step is s times the clip's (slerp of a constant-rate rotation stays on its great circle)."""
    clip = _clip(200)
    aug = MotionAugmentation(0.0, (speed, speed))
    w = augmented_window(clip, 50, np.random.default_rng(seed), aug)
    assert w.local_quats.shape == (50, _J, 4)
    assert w.root_pos.shape == (50, 3)
    np.testing.assert_allclose(np.diff(w.root_pos[:, 0]), 0.01 * speed, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(w.local_quats, axis=-1), 1.0, atol=1e-12)
    step = np.abs(np.sum(w.local_quats[1:] * w.local_quats[:-1], axis=-1))
    base = np.abs(np.sum(clip.local_quats[1:] * clip.local_quats[:-1], axis=-1))
    # rotation angle per frame, from |cos(θ/2)|: the clip's rate × speed
    got = 2 * np.arccos(np.clip(step, -1, 1)).mean(axis=0)
    want = 2 * np.arccos(np.clip(base, -1, 1)).mean(axis=0) * speed
    np.testing.assert_allclose(got, want, rtol=0.02, atol=1e-6)


def test_a_resampled_window_ignores_quaternion_signs() -> None:
    """q and −q are one rotation: a clip whose signs flip every frame plays as the smooth one."""
    clip = _clip(200)
    flipped = np.array(clip.local_quats)
    flipped[1::2] *= -1.0
    signed = dataclasses.replace(clip, local_quats=flipped)
    aug = MotionAugmentation(0.0, (1.3, 1.3))
    a = augmented_window(clip, 50, np.random.default_rng(9), aug)
    b = augmented_window(signed, 50, np.random.default_rng(9), aug)
    np.testing.assert_allclose(np.abs(np.sum(a.local_quats * b.local_quats, axis=-1)), 1.0)


def test_both_views_of_a_window_see_the_same_augmented_motion() -> None:
    clips = (_clip(120, 0), _clip(150, 1))
    dataset = MotionDataset(clips, "hash", 30.0)
    sampler = TwoViewSampler(
        dataset,
        window_frames=32,
        batch_size=4,
        seed=2,
        augment=MotionAugmentation(0.5, (0.8, 1.25)),
    )
    batch = sampler.sample(5)
    views_a, views_b = batch.targets[:4], batch.targets[4:]
    # Targets differ only in the root's heading (each camera's); the body is the same motion.
    assert torch.allclose(views_a[:, :, 1:], views_b[:, :, 1:])
    assert torch.equal(sampler.sample(5).features, batch.features)


def test_windows_too_long_for_the_fastest_speed_are_refused() -> None:
    with pytest.raises(ValueError, match="a window needs"):
        augmented_window(
            _clip(60), 50, np.random.default_rng(0), MotionAugmentation(0.0, (1.5, 1.5))
        )


def test_train_flags_are_checked() -> None:
    assert _motion_augmentation(0.5, "0.8,1.25") == MotionAugmentation(0.5, (0.8, 1.25))
    for mirror, speed in ((1.5, "1,1"), (0.5, "1.2,0.9"), (0.5, "fast"), (0.5, "0,1")):
        with pytest.raises(TrainArgumentError, match="--speed-range"):
            _motion_augmentation(mirror, speed)
    assert dataclasses.replace(MotionAugmentation(), mirror_probability=0.0).active is False
    assert _motion_augmentation(0.0, "1,1", 0.5).active
    with pytest.raises(TrainArgumentError, match="--arm-mix-probability"):
        _motion_augmentation(0.0, "1,1", 1.5)


def _where_from(window: np.ndarray, donor: Clip) -> int | None:
    """The start of the donor window ``window`` (T, k, 4) was cut from, or None."""
    frames = window.shape[0]
    for start in range(donor.num_frames - frames + 1):
        if np.array_equal(donor.local_quats[start : start + frames][:, : window.shape[1]], window):
            return start
    return None


def test_mixed_arms_come_whole_from_donor_windows() -> None:
    """Probability 1: each arm (shoulder to hand) is one donor window's, frame for frame; every
    other joint and the root are the clip's own slice."""
    clip, donor = _clip(120, 0), _clip(90, 7)
    aug = MotionAugmentation(0.0, (1.0, 1.0), arm_mix_probability=1.0)
    w = augmented_window(clip, 40, np.random.default_rng(4), aug, donors=(donor,))
    start = int(w.name.split("@")[1])
    arms = [j for joints in ARM_JOINTS for j in joints]
    rest = [j for j in range(_J) if j not in arms]
    np.testing.assert_allclose(
        w.local_quats[:, rest], clip.local_quats[start : start + 40][:, rest]
    )
    np.testing.assert_allclose(w.root_pos, clip.root_pos[start : start + 40])
    for joints in ARM_JOINTS:
        got = w.local_quats[:, list(joints)]
        assert not np.allclose(got, clip.local_quats[start : start + 40][:, list(joints)])
        donor_arm = dataclasses.replace(donor, local_quats=donor.local_quats[:, list(joints)])
        assert _where_from(got, donor_arm) is not None


def test_arm_mixing_needs_donors_and_a_probability() -> None:
    aug = MotionAugmentation(0.0, (1.0, 1.0), arm_mix_probability=1.0)
    with pytest.raises(ValueError, match="donor"):
        augmented_window(_clip(), 40, np.random.default_rng(0), aug)
    with pytest.raises(ValueError, match="a window needs"):
        augmented_window(_clip(), 40, np.random.default_rng(0), aug, donors=(_clip(30, 1),))
    with pytest.raises(ValueError, match="arm mix probability"):
        MotionAugmentation(arm_mix_probability=-0.1)
