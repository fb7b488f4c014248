"""The robustness table: every model under clean input and each corruption kind."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_retarget.evaluation.robustness import markdown, robustness
from robot_retarget.robot.loader import load_robot_config


def test_a_row_per_model_and_kind_with_the_rise_over_clean(shared_data_dir: Path) -> None:
    config = load_robot_config("op3")
    clip = shared_data_dir / "mocap" / "02" / "02_01.bvh"
    rows = robustness(config, [("02_01", clip)], ["copy", "copy-scaled"], ["jitter", "swap"],
                      max_frames=300)  # fmt: skip
    assert [(r.model, r.kind) for r in rows] == [
        ("copy", "clean"), ("copy", "jitter"), ("copy", "swap"),
        ("copy-scaled", "clean"), ("copy-scaled", "jitter"), ("copy-scaled", "swap"),
    ]  # fmt: skip
    clean, jitter, swap = rows[:3]
    assert jitter.jerk_rad_s3 > clean.jerk_rad_s3  # jitter shakes the servos
    # The robot's deviation from its clean-input run: none for clean input and for short swaps
    # (the live source swaps them back exactly), degrees for jitter.
    assert clean.deviation_deg == 0.0
    assert swap.deviation_deg == pytest.approx(0.0, abs=1e-6)
    assert jitter.deviation_deg > 1.0
    text = markdown(rows)
    assert "| jitter |" in text
    assert "(+0.00) / 0.00° /" in text  # clean against itself
