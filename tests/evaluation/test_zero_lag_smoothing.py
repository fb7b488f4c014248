"""The zero-lag bound of ``eval-robot --corrupt --oracle-smoothing``: a centred Gaussian over
the sender's timestamps, bones smoothed as directions and lengths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.evaluation.live_corruption import CorruptedStream, corrupt_stream
from robot_retarget.evaluation.zero_lag_smoothing import GaussianKernel, zero_lag_smoothed
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS


def _bone_angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = []
    for j, p in enumerate(CANONICAL_PARENTS):
        if p < 0:
            continue
        u, v = a[:, j] - a[:, p], b[:, j] - b[:, p]
        if np.linalg.norm(v, axis=1).min() < 1e-6:
            continue
        cross = np.linalg.norm(np.cross(u, v), axis=1)
        out.append(np.degrees(np.arctan2(cross, np.sum(u * v, axis=1))))
    return np.array(out)


@settings(max_examples=40, deadline=None)
@given(
    times=st.lists(st.floats(0.001, 0.2), min_size=2, max_size=40),
    sigma=st.floats(0.001, 1.0),
)
def test_weights_are_centred_and_sum_to_one(times: list[float], sigma: float) -> None:
    t = np.cumsum(times)
    w = GaussianKernel(t, sigma).dense()
    assert np.allclose(w.sum(axis=1), 1.0)
    assert (w >= 0.0).all()
    # Centred: each frame weighs another by its time distance alone, before or after alike.
    d = (t[:, None] - t[None, :]) / sigma
    expected = np.where(np.abs(d) <= 4.0 + 1e-9, np.exp(-0.5 * d * d), 0.0)
    assert np.allclose(w / np.diag(w)[:, None], expected)
    even = GaussianKernel(np.arange(41) * 0.01, 0.03).dense()
    assert np.allclose(even[20, :20], even[20, 21:][::-1])


def test_a_bad_sigma_is_refused() -> None:
    for bad in (0.0, -0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="sigma"):
            GaussianKernel(np.arange(3.0), bad)


def test_it_removes_jitter_without_lag_and_keeps_the_bones() -> None:
    """On a jittered stream the smoothed bones come nearer the clean ones; a clean stream
    barely moves (no lag: a causal filter of the same width would trail the motion); every
    rebuilt bone keeps the sender's mean length."""
    motion = demo_motion(fps=120.0).frames(0, 360)
    clean = corrupt_stream(motion, "clean", np.random.default_rng(0))
    jitter = corrupt_stream(motion, "jitter", np.random.default_rng(0))
    smoothed = zero_lag_smoothed(jitter, 0.04)
    truth = clean.positions
    inner = slice(30, -30)  # away from the ends, where the kernel is one-sided
    before = _bone_angles_deg(jitter.positions[inner], truth[inner]).mean()
    after = _bone_angles_deg(smoothed.positions[inner], truth[inner]).mean()
    assert after < 0.5 * before
    clean_smoothed = zero_lag_smoothed(clean, 0.04)
    assert _bone_angles_deg(clean_smoothed.positions[inner], truth[inner]).mean() < 1.0
    assert smoothed.kind == "jitter"
    assert np.array_equal(smoothed.t_s, jitter.t_s)
    for j, p in enumerate(CANONICAL_PARENTS):
        if p >= 0:
            sent = np.linalg.norm(jitter.positions[:, j] - jitter.positions[:, p], axis=1)
            got = np.linalg.norm(smoothed.positions[:, j] - smoothed.positions[:, p], axis=1)
            assert got.mean() == pytest.approx(sent.mean(), rel=0.02, abs=1e-6)


def test_a_straight_line_passes_unchanged_inside_the_stream() -> None:
    """A root moving at constant velocity, bones fixed: a centred kernel reproduces it exactly
    where it has frames on both sides (a causal one would lag by its delay)."""
    n = 200
    t = np.arange(n) / 100.0
    pos = np.zeros((n, len(CANONICAL_PARENTS), 3))
    rest = np.random.default_rng(3).normal(size=(len(CANONICAL_PARENTS), 3)) * 0.1
    for j, p in enumerate(CANONICAL_PARENTS):
        pos[:, j] = (pos[:, p] if p >= 0 else 0.0) + rest[j]
    pos += (t[:, None] * np.array([0.5, 0.0, 1.0]))[:, None, :]
    out = zero_lag_smoothed(CorruptedStream(pos, t, "clean"), 0.05)
    assert np.allclose(out.positions[30:-30], pos[30:-30], atol=1e-9)


def test_eval_robot_takes_it_only_with_corrupt(capsys: pytest.CaptureFixture[str]) -> None:
    from robot_retarget.cli.main import main

    with pytest.raises(SystemExit, match="--oracle-smoothing smooths the senders"):
        main(["eval-robot", "--oracle-smoothing", "40"])
    for bad in ("0", "-5", "nan"):
        with pytest.raises(SystemExit) as info:
            main(["eval-robot", "--corrupt", "jitter", "--oracle-smoothing", bad])
        assert info.value.code == 2
        assert "--oracle-smoothing" in capsys.readouterr().err


def test_the_bound_runs_through_the_robustness_table(shared_data_dir: Path) -> None:
    """Jitter smoothed with no lag moves the robot less, and less far from the performer, than
    jitter as the live source filters it alone."""
    from robot_retarget.evaluation.robustness import robustness
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config("op3")
    clip = [("02_01", shared_data_dir / "mocap" / "02" / "02_01.bvh")]
    plain = robustness(config, clip, ["copy-scaled"], ["jitter"], max_frames=300)
    bound = robustness(config, clip, ["copy-scaled"], ["jitter"], max_frames=300,
                       oracle_smoothing_s=0.04)  # fmt: skip
    assert bound[1].deviation_deg < plain[1].deviation_deg
    assert bound[1].direction_deg < plain[1].direction_deg
