"""Frozen joints carried by their parents, swapped limbs swapped back (the live positions
receiver's cleanup), alone, together, on the corruption model's streams and through UdpSource.
The cleanup's jitter filter has its own tests (test_jitter_filter.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.array_types import FloatArray
from robot_retarget.evaluation.live_corruption import corrupt_stream, jitter_gains
from robot_retarget.motion.human_motion import skeleton_height
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.skeleton.canonical import ARM_CHAINS, CANONICAL_PARENTS, LEG_CHAINS, Joint
from robot_retarget.sources import wire
from robot_retarget.sources.frozen_joints import FrozenJointFill
from robot_retarget.sources.limb_swaps import MAX_GAP_S, LimbSwapFix
from robot_retarget.sources.position_cleanup import PositionCleanup
from robot_retarget.sources.udp import UdpSource

_ARM_L, _ARM_R = (list(c) for c in ARM_CHAINS)


@pytest.fixture(scope="module")
def walk() -> FloatArray:
    """Canonical joint positions of the demo routine at 30 fps (a live sender's rate)."""
    return demo_motion(fps=30.0).frames(0, 181).positions()


_FPS = 30.0


def _run(rule: FrozenJointFill | LimbSwapFix | PositionCleanup, frames: FloatArray) -> FloatArray:
    """The rule over frames sent at 30 fps."""
    if isinstance(rule, FrozenJointFill):
        return np.stack([rule(p) for p in frames])
    return np.stack([rule(p, k / _FPS) for k, p in enumerate(frames)])


def _swap_arms(p: FloatArray) -> FloatArray:
    out = p.copy()
    out[_ARM_L + _ARM_R] = p[_ARM_R + _ARM_L]
    return out


# --------------------------------------------------------------------------- frozen joints
def test_a_stream_without_repeats_passes_unchanged(walk: FloatArray) -> None:
    out = _run(FrozenJointFill(CANONICAL_PARENTS), walk)
    np.testing.assert_array_equal(out, walk)


@settings(max_examples=30, deadline=None)
@given(
    joint=st.integers(1, 21),
    start=st.integers(1, 150),
    length=st.integers(1, 30),
    velocity=st.tuples(*[st.floats(-2.0, 2.0)] * 3),
)
def test_a_frozen_joint_on_a_translating_body_is_recovered_exactly(
    walk: FloatArray, joint: int, start: int, length: int, velocity: tuple[float, float, float]
) -> None:
    # A rigid body gliding at a constant velocity: a joint's bone does not change, so carrying
    # the frozen joint with its parent gives its true position back.
    pose = walk[0]
    truth = pose[None] + np.arange(len(walk))[:, None, None] * np.array(velocity) / 30.0
    sent = truth.copy()
    stop = min(start + length, len(walk))
    sent[start:stop, joint] = sent[start - 1, joint]
    moving = bool(np.any(np.array(velocity) != 0.0))
    fill = FrozenJointFill(CANONICAL_PARENTS)
    out = _run(fill, sent)
    if moving:
        np.testing.assert_allclose(out, truth, atol=1e-12)
    else:  # nothing moves: every frame is a repeat, and passes as sent
        np.testing.assert_array_equal(out, sent)


def test_a_frozen_chain_is_carried_root_outward(walk: FloatArray) -> None:
    truth = walk[0][None] + np.arange(40)[:, None, None] * np.array([0.04, 0.0, 0.0])
    sent = truth.copy()
    chain = [Joint.LeftArm, Joint.LeftForeArm, Joint.LeftHand]
    sent[10:30, chain] = sent[9, chain]
    fill = FrozenJointFill(CANONICAL_PARENTS)
    out = _run(fill, sent)
    np.testing.assert_allclose(out, truth, atol=1e-12)
    fill(sent[-1] + 0.01)
    assert not fill.frozen.any()


def test_the_root_and_whole_repeats_are_never_filled(walk: FloatArray) -> None:
    fill = FrozenJointFill(CANONICAL_PARENTS)
    fill(walk[0])
    moved_but_root = walk[1].copy()
    moved_but_root[0] = walk[0][0]
    np.testing.assert_array_equal(fill(moved_but_root), moved_but_root)
    np.testing.assert_array_equal(fill(moved_but_root), moved_but_root)  # a repeat
    assert not fill.frozen.any()


def test_a_repeated_frame_gets_the_same_answer(walk: FloatArray) -> None:
    # A sender repeating frames (a 30 fps estimator sent at 60 fps) during a dropout: the
    # repeat keeps the filled joint where the frame before put it.
    truth = walk[0][None] + np.arange(12)[:, None, None] * np.array([0.04, 0.0, 0.0])
    sent = truth.copy()
    sent[4:, Joint.LeftHand] = sent[3, Joint.LeftHand]
    sent = np.concatenate([sent[:6], sent[5:6], sent[6:]])  # frame 5 twice
    out = _run(FrozenJointFill(CANONICAL_PARENTS), sent)
    np.testing.assert_array_equal(out[6], out[5])
    np.testing.assert_allclose(out[:6], truth[:6], atol=1e-12)
    np.testing.assert_allclose(out[7:], truth[6:], atol=1e-12)


def test_reset_forgets_the_last_frame(walk: FloatArray) -> None:
    fill = FrozenJointFill(CANONICAL_PARENTS)
    fill(walk[0])
    held = walk[5].copy()
    held[Joint.LeftHand] = walk[0][Joint.LeftHand]
    fill.reset()
    np.testing.assert_array_equal(fill(held), held)  # a first frame again: taken as sent


def test_frozen_fill_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="must come before it"):
        FrozenJointFill((-1, 2, 0))
    with pytest.raises(ValueError, match="must be the root"):
        FrozenJointFill((0, -1))
    with pytest.raises(ValueError, match=r"shape \(22, 3\)"):
        FrozenJointFill(CANONICAL_PARENTS)(np.zeros((21, 3)))


# --------------------------------------------------------------------------- limb swaps
def test_unswapped_streams_pass_unchanged_even_when_jittery(walk: FloatArray) -> None:
    rng = np.random.default_rng(3)
    height = skeleton_height(demo_motion(fps=30.0).skeleton)
    sigma = 0.01 * height * jitter_gains()
    jittery = walk + rng.normal(size=walk.shape) * sigma[None, :, None]
    for frames in (walk, jittery):
        fix = LimbSwapFix((ARM_CHAINS, LEG_CHAINS))
        np.testing.assert_array_equal(_run(fix, frames), frames)


@settings(max_examples=30, deadline=None)
@given(start=st.integers(1, 160), length=st.integers(1, 14))
def test_a_short_swap_is_swapped_back(walk: FloatArray, start: int, length: int) -> None:
    # Up to 14 frames at 30 fps: shorter than the 0.5 s a run is corrected for.
    sent = walk.copy()
    stop = min(start + length, len(walk))
    sent[start:stop] = np.stack([_swap_arms(p) for p in walk[start:stop]])
    fix = LimbSwapFix((ARM_CHAINS, LEG_CHAINS))
    np.testing.assert_array_equal(_run(fix, sent), walk)


def test_a_stream_that_starts_swapped_is_followed_at_most_max_swap_s(walk: FloatArray) -> None:
    # Taken as sent at first; when its labels turn right the rule swaps them back to the
    # first ones, but for max_swap_s only (here 5.5 frames: 6 frames).
    sent = np.stack([_swap_arms(p) for p in walk[:60]] + list(walk[60:]))
    fix = LimbSwapFix((ARM_CHAINS, LEG_CHAINS), max_swap_s=5.5 / _FPS)
    out = _run(fix, sent)
    differs = np.flatnonzero((out != sent).any(axis=(1, 2)))
    np.testing.assert_array_equal(differs, np.arange(60, 66))
    np.testing.assert_array_equal(out[66:], walk[66:])


def test_a_long_swap_is_corrected_then_believed_and_its_end_passes(walk: FloatArray) -> None:
    # Ten swapped frames against a 6-frame limit: 6 corrected, 4 pass as sent, and the
    # sender's return to the right labels is not taken for a swap.
    sent = walk.copy()
    sent[60:70] = np.stack([_swap_arms(p) for p in walk[60:70]])
    out = _run(LimbSwapFix((ARM_CHAINS, LEG_CHAINS), max_swap_s=5.5 / _FPS), sent)
    np.testing.assert_array_equal(out[:66], walk[:66])
    np.testing.assert_array_equal(out[66:70], sent[66:70])
    np.testing.assert_array_equal(out[70:], walk[70:])


def test_after_a_silence_the_labels_are_taken_as_sent(walk: FloatArray) -> None:
    # The performer turns round while the sender is silent: the mirrored-looking frame after
    # the silence is not a swap.
    turned = walk[40:80] * np.array([-1.0, 1.0, -1.0])  # half a turn about the vertical
    fix = LimbSwapFix((ARM_CHAINS, LEG_CHAINS))
    for k, p in enumerate(walk[:40]):
        fix(p, k / _FPS)
    resume = 39 / _FPS + MAX_GAP_S + 0.01
    out = np.stack([fix(p, resume + k / _FPS) for k, p in enumerate(turned)])
    np.testing.assert_array_equal(out, turned)
    # Without the silence the same frames would have been swapped back.
    fix = LimbSwapFix((ARM_CHAINS, LEG_CHAINS))
    for k, p in enumerate(walk[:40]):
        fix(p, k / _FPS)
    fix(turned[0], 40 / _FPS)
    assert any(fix.swapped)


def test_limb_swap_fix_refuses_bad_pairs() -> None:
    with pytest.raises(ValueError, match="disjoint chains of equal length"):
        LimbSwapFix((((1, 2), (2, 3)),))
    with pytest.raises(ValueError, match="disjoint chains of equal length"):
        LimbSwapFix((((1, 2), (3,)),))
    with pytest.raises(ValueError, match="max_swap_s and max_gap_s"):
        LimbSwapFix((ARM_CHAINS,), max_swap_s=-1.0)


# --------------------------------------------------------------------------- both, live
def _cleaned(positions: FloatArray, t_s: FloatArray) -> FloatArray:
    cleanup = PositionCleanup()
    return np.stack([cleanup(p, t) for p, t in zip(positions, t_s, strict=True)])


def test_cleanup_undoes_the_modelled_dropouts_and_swaps() -> None:
    clip = demo_motion(fps=30.0).frames(0, 181)
    truth = clip.positions()
    for kind, seed in (("swap", 1), ("swap", 2), ("dropout", 1), ("dropout", 2)):
        stream = corrupt_stream(clip, kind, np.random.default_rng(seed))
        frames = np.rint(stream.t_s * clip.fps).astype(int)
        raw_error = np.linalg.norm(stream.positions - truth[frames], axis=-1).mean()
        out = _cleaned(stream.positions, stream.t_s)
        error = np.linalg.norm(out - truth[frames], axis=-1).mean()
        if kind == "swap":  # the clean frames, as the cleanup (its jitter filter) passes them
            np.testing.assert_array_equal(out, _cleaned(truth[frames], stream.t_s))
        else:
            assert error < 0.5 * raw_error, (kind, seed, error, raw_error)


def test_udp_positions_are_cleaned_and_a_restart_starts_over(walk: FloatArray) -> None:
    def received(src: UdpSource, seq: int, t_s: float, pos: FloatArray) -> FloatArray:
        frame = src.handle_packet(wire.encode_binary(wire.KIND_POSITIONS, seq, t_s, pos), 0.0)
        assert frame is not None
        return frame.local_quats

    f32 = walk.astype(np.float32).astype(np.float64)  # what the binary wire carries
    held = f32[1].copy()
    held[Joint.LeftHand] = f32[0][Joint.LeftHand]
    swapped = _swap_arms(f32[1])
    clean, raw = UdpSource("127.0.0.1", 0), UdpSource("127.0.0.1", 0, clean_positions=False)
    truth = UdpSource("127.0.0.1", 0)
    for src in (clean, raw, truth):
        received(src, 1, 0.0, f32[0])
    expect = received(truth, 2, 0.033, f32[1])
    got_clean, got_raw = received(clean, 2, 0.033, held), received(raw, 2, 0.033, held)
    assert not np.allclose(got_raw, expect)
    np.testing.assert_allclose(got_clean, expect, atol=0.05)  # the hand's bone as last seen
    # The sender restarts (sequence and clock start over): a swapped first frame is its own.
    np.testing.assert_allclose(received(clean, 3, 0.066, swapped), expect, atol=1e-9)
    first = received(clean, 0, 0.0, swapped)
    np.testing.assert_allclose(first, received(raw, 0, 0.0, swapped), atol=1e-12)
