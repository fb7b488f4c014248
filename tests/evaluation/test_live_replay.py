"""A sender through the real control loop, scored against the clean performer."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.errors import InvalidMotionError
from robot_retarget.evaluation.live_corruption import corrupt_stream
from robot_retarget.evaluation.live_replay import LiveScore, deviation_deg, score_live
from robot_retarget.evaluation.robot.segments import BodyPoints
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn.inference import load_model
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.loader import load_robot_config


def test_clean_input_scores_better_than_jittered_and_swapped() -> None:
    config = load_robot_config("op3")
    clip = demo_motion(fps=30.0).frames(0, 151)
    step = RetargetStep(config, load_model("copy"), clip.skeleton)
    rng = np.random.default_rng(0)
    clean = score_live(step, clip, corrupt_stream(clip, "clean", rng))
    jitter = score_live(step, clip, corrupt_stream(clip, "jitter", rng, severity=2.0))
    swapped = corrupt_stream(clip, "swap", rng, severity=3.0)
    swap_raw = score_live(step, clip, swapped, clean_positions=False)
    swap = score_live(step, clip, swapped)
    assert clean.commands > 400  # 4 s at 125 Hz after the first second
    assert clean.direction_deg < jitter.direction_deg
    assert clean.jerk_rad_s3 < jitter.jerk_rad_s3  # jitter shakes the servos
    # Solved as sent, swapped limbs cost; the live source swaps them back (short swaps exactly).
    assert clean.direction_deg < swap_raw.direction_deg
    assert swap.direction_deg == pytest.approx(clean.direction_deg, abs=1e-9)
    # The deviation from the clean run: none for a run that plays the clean commands, some for
    # jitter and for swaps solved as sent.
    assert deviation_deg(clean, clean) == 0.0
    assert deviation_deg(swap, clean) == pytest.approx(0.0, abs=1e-6)
    assert deviation_deg(jitter, clean) > 1.0
    assert deviation_deg(swap_raw, clean) > 0.1


def _score(t: np.ndarray, directions: np.ndarray) -> LiveScore:
    return LiveScore(0.0, 0.0, len(t), t, BodyPoints(directions, np.zeros((len(t), 4, 3))))


def test_deviation_is_the_angle_to_the_reference_command_nearest_in_time() -> None:
    t_ref = np.arange(100) / 125.0
    angle = np.radians(np.arange(100) * 0.5)  # each reference command its own direction
    ref_dirs = np.stack([np.cos(angle), np.sin(angle), np.zeros(100)], -1)[:, None].repeat(9, 1)
    # A run played at other instants, each 0.4 ticks after a reference command, turned 10°
    # further about z: nearest-time matching must find that command, not a neighbour.
    t_run = t_ref[:-1] + 0.4 / 125.0
    turned = angle[:-1] + np.radians(10.0)
    run_dirs = np.stack([np.cos(turned), np.sin(turned), np.zeros(99)], -1)[:, None].repeat(9, 1)
    assert deviation_deg(_score(t_run, run_dirs), _score(t_ref, ref_dirs)) == pytest.approx(10.0)
    with pytest.raises(ValueError, match="scored commands"):
        deviation_deg(_score(t_run[:0], run_dirs[:0]), _score(t_ref, ref_dirs))


def test_a_clip_shorter_than_the_settling_time_is_refused() -> None:
    config = load_robot_config("op3")
    clip = demo_motion(fps=30.0).frames(0, 10)
    step = RetargetStep(config, load_model("copy"), clip.skeleton)
    with pytest.raises(InvalidMotionError, match=r"10 frames \(0.33 s at 30 fps\).*at least 31"):
        score_live(step, clip, corrupt_stream(clip, "clean", np.random.default_rng(0)))
