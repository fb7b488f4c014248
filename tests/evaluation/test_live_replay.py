"""A sender through the real control loop, scored against the clean performer."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.evaluation.live_corruption import corrupt_stream
from robot_retarget.evaluation.live_replay import score_live
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


def test_a_clip_shorter_than_the_settling_time_is_refused() -> None:
    config = load_robot_config("op3")
    clip = demo_motion(fps=30.0).frames(0, 10)
    step = RetargetStep(config, load_model("copy"), clip.skeleton)
    with pytest.raises(ValueError, match="too short"):
        score_live(step, clip, corrupt_stream(clip, "clean", np.random.default_rng(0)))
