"""The opt-in One-Euro input filter: passes a still pose unchanged, follows a step, smooths
jitter, lags less when the input moves fast, and starts over on reset."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.pipeline.input_filter import OneEuroFilter, OneEuroSettings

DT = 1.0 / 125.0


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return 2.0 * np.arccos(np.abs(np.sum(a * b, axis=-1)).clip(0.0, 1.0))


@settings(max_examples=30, deadline=None)
@given(arrays(np.float64, (22, 3), elements=st.floats(-3.0, 3.0)), st.floats(-5.0, 5.0))
def test_a_still_pose_passes_unchanged(rotvecs: np.ndarray, x: float) -> None:
    q = quat.from_rotation_vector(rotvecs)
    root = np.array([x, 0.9, -x])
    f = OneEuroFilter(OneEuroSettings())
    for _ in range(20):
        out_q, out_root = f(q, root, DT)
    assert float(_angle(out_q, q).max()) < 1e-6
    np.testing.assert_allclose(out_root, root, atol=1e-12)


def test_it_follows_a_step_and_smooths_jitter() -> None:
    rng = np.random.default_rng(0)
    start = np.tile([1.0, 0.0, 0.0, 0.0], (22, 1))
    goal = quat.from_rotation_vector(np.tile([0.0, 0.5, 0.0], (22, 1)))
    f = OneEuroFilter(OneEuroSettings(min_cutoff_hz=2.0, beta=0.3))
    f(start, np.zeros(3), DT)
    for _ in range(250):  # 2 s after a step: settled on the new pose
        out, _ = f(goal, np.zeros(3), DT)
    assert float(_angle(out, goal).max()) < 1e-3
    # Jitter of 0.1 rad per frame around the goal: the output's spread is much smaller.
    outs, ins = [], []
    for _ in range(500):
        noisy = quat.mul(goal, quat.from_rotation_vector(rng.normal(0.0, 0.1, (22, 3))))
        out, _ = f(noisy, np.zeros(3), DT)
        ins.append(_angle(noisy, goal).mean())
        outs.append(_angle(out, goal).mean())
    assert np.mean(outs) < 0.5 * np.mean(ins)


def test_a_fast_motion_lags_less_with_a_larger_beta() -> None:
    """A joint turning at 3 rad/s: the speed-dependent cutoff keeps up."""
    lags = []
    for beta in (0.0, 1.0):
        f = OneEuroFilter(OneEuroSettings(min_cutoff_hz=1.0, beta=beta))
        for k in range(200):
            q = quat.from_rotation_vector(np.tile([0.0, 3.0 * k * DT, 0.0], (22, 1)))
            out, _ = f(q, np.zeros(3), DT)
        lags.append(float(_angle(out, q).mean()))
    assert lags[1] < 0.5 * lags[0]


def test_reset_starts_over() -> None:
    f = OneEuroFilter(OneEuroSettings())
    a = np.tile([1.0, 0.0, 0.0, 0.0], (22, 1))
    b = quat.from_rotation_vector(np.tile([1.0, 0.0, 0.0], (22, 1)))
    f(a, np.zeros(3), DT)
    f.reset()
    out, root = f(b, np.ones(3), DT)  # the first frame after a reset passes through
    np.testing.assert_allclose(out, b)
    np.testing.assert_allclose(root, np.ones(3))


@pytest.mark.parametrize(
    "text", ["2", "a,b", "2,0.3,1", "0,0.3", "-1,0.3", "2,-0.1", "nan,0.3", "inf,1"]
)
def test_bad_settings_are_refused_with_the_form(text: str) -> None:
    with pytest.raises(ValueError, match=r"MIN_HZ,BETA"):
        OneEuroSettings.parse(text)


def test_the_loop_applies_it_and_restarts_it_with_each_sequence() -> None:
    """Through the control loop on the simulated clock: with the filter, the commands of a
    jittery sender move less from tick to tick than without."""
    from robot_retarget.evaluation.live_corruption import corrupt_stream
    from robot_retarget.evaluation.live_replay import score_live
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config("op3")
    motion = demo_motion(fps=30.0).frames(0, 120)
    step = RetargetStep(config, "copy-scaled", motion.skeleton)
    jerk = []
    for smooth in (None, OneEuroSettings()):
        stream = corrupt_stream(motion, "jitter", np.random.default_rng(1))
        jerk.append(score_live(step, motion, stream, input_filter=smooth).jerk_rad_s3)
    assert jerk[1] < 0.7 * jerk[0]


def test_eval_robot_takes_it_only_with_corrupt(capsys: pytest.CaptureFixture[str]) -> None:
    """``eval-robot --one-euro`` smooths the live loop of ``--corrupt``; without it (nothing
    to smooth) or with a malformed value it is refused before any work."""
    from robot_retarget.cli.main import main

    with pytest.raises(SystemExit, match="add --corrupt"):
        main(["eval-robot", "--one-euro", "2,0.3"])
    with pytest.raises(SystemExit, match="--raw-positions is about the live source"):
        main(["eval-robot", "--raw-positions"])
    with pytest.raises(SystemExit) as info:
        main(["eval-robot", "--corrupt", "jitter", "--one-euro", "2"])
    assert info.value.code == 2
    assert "MIN_HZ,BETA" in capsys.readouterr().err
