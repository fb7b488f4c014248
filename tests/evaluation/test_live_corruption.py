"""Live-input corruption kinds: each changes what it says and nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.evaluation.live_corruption import KINDS, CorruptedStream, corrupt_stream
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint


@pytest.fixture(scope="module")
def clip() -> HumanMotion:
    return demo_motion(fps=30.0).frames(0, 181)  # 6 s


def _corrupt(clip: HumanMotion, kind: str, seed: int = 0) -> CorruptedStream:
    return corrupt_stream(clip, kind, np.random.default_rng(seed))


def test_clean_is_the_clip(clip: HumanMotion) -> None:
    s = _corrupt(clip, "clean")
    np.testing.assert_allclose(s.positions, clip.positions())
    np.testing.assert_allclose(s.t_s, np.arange(clip.num_frames) / clip.fps)


def test_jitter_is_largest_at_wrists_and_ankles(clip: HumanMotion) -> None:
    err = np.linalg.norm(_corrupt(clip, "jitter").positions - clip.positions(), axis=-1)
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[Joint.LeftHand] > 2.0 * rms[Joint.Spine1]
    assert rms[Joint.RightFoot] > 2.0 * rms[Joint.Neck]
    assert 0.01 < rms[Joint.Spine1] < 0.05  # ≈ 1 % of a 1.5 m height × √3


def test_dropouts_remove_frames_and_freeze_joints(clip: HumanMotion) -> None:
    s = _corrupt(clip, "dropout")
    assert 0.8 * clip.num_frames < len(s.t_s) < clip.num_frames
    gaps = np.diff(np.rint(s.t_s * clip.fps))
    assert gaps.max() >= 2
    assert gaps.max() <= 31
    frozen = np.all(np.diff(s.positions, axis=0) == 0.0, axis=-1)  # (N-1, J) held positions
    assert frozen[:, 1:].any()


def test_swaps_exchange_left_and_right_limbs(clip: HumanMotion) -> None:
    s = _corrupt(clip, "swap")
    clean = clip.positions()
    swapped = np.all(np.isclose(s.positions[:, Joint.LeftHand], clean[:, Joint.RightHand]), -1)
    assert 0 < swapped.sum() < 0.2 * clip.num_frames


def test_bone_lengths_change_but_the_root_does_not(clip: HumanMotion) -> None:
    s = _corrupt(clip, "bone_length")
    clean = clip.positions()
    np.testing.assert_allclose(s.positions[:, 0], clean[:, 0])
    j, parent = Joint.LeftLeg, CANONICAL_PARENTS[Joint.LeftLeg]
    ratio = np.linalg.norm(s.positions[:, j] - s.positions[:, parent], axis=-1) / np.linalg.norm(
        clean[:, j] - clean[:, parent], axis=-1
    )
    assert 0.01 < ratio.std() < 0.1


def test_latency_delays_by_two_to_four_frames(clip: HumanMotion) -> None:
    s = _corrupt(clip, "latency")
    clean = clip.positions()
    delay = next(d for d in range(2, 5) if np.allclose(s.positions[d:], clean[:-d]))
    assert 2 <= delay <= 4


def test_low_rate_is_30_fps() -> None:
    clip = demo_motion(fps=120.0).frames(0, 241)
    s = _corrupt(clip, "low_rate")
    np.testing.assert_allclose(np.diff(s.t_s), 1 / 30)


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_is_reproducible(clip: HumanMotion, kind: str) -> None:
    a, b = _corrupt(clip, kind, 3), _corrupt(clip, kind, 3)
    np.testing.assert_array_equal(a.positions, b.positions)


def test_bad_arguments(clip: HumanMotion) -> None:
    with pytest.raises(ValueError, match="unknown corruption"):
        _corrupt(clip, "fog")
    with pytest.raises(ValueError, match="severity"):
        corrupt_stream(clip, "jitter", np.random.default_rng(0), severity=-1.0)
