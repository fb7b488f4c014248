"""eval-robot's runner on the built-in demo motion (no data files) and on real clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import SourceError
from robot_retarget.evaluation.robot.runner import (
    METHODS,
    EvalRobotReport,
    EvalRobotSettings,
    RobotEvaluator,
    evaluate_robot,
    oracle_runner,
    pipeline_runner,
    summarize,
    validation_clips,
    with_retarget_overrides,
)
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.robot.config import RobotConfig


@pytest.fixture(scope="module")
def demo_report(op3: RobotConfig) -> EvalRobotReport:
    """1.5 s of the demo routine (from its wave), scored at 25 fps."""
    motion = demo_motion(fps=125.0).frames(250, 438)
    ev = RobotEvaluator(op3, pipeline_runner(op3, "copy"), EvalRobotSettings(stride=5))
    clip = ev.score_motion(motion, "demo")
    return EvalRobotReport("op3", "copy", (clip,), summarize([clip]), 125.0, 5, 38, 0.0)


def test_limit_is_never_worse_than_any_method(demo_report: EvalRobotReport) -> None:
    clip = demo_report.clips[0]
    limit = clip.methods["limit"].angles.mean(axis=1)
    for other in ("pipeline", "gmr", "baseline"):
        assert np.all(limit <= clip.methods[other].angles.mean(axis=1) + 1e-9)


def test_every_method_is_scored(demo_report: EvalRobotReport) -> None:
    clip = demo_report.clips[0]
    assert clip.human_positions.shape == (38, 22, 3)
    for m in METHODS:
        assert clip.methods[m].angles.shape == (38, 9)
        assert clip.methods[m].ee.shape == (38, 4)
        assert clip.robot_q[m].shape == (38, 20)
    for m in ("pipeline", "gmr", "baseline"):
        s = demo_report.summary[m]
        assert s.limit_violations == 0
        assert s.speed_violations == 0
        assert s.jerk_rad_s3 is not None
        assert s.jerk_rad_s3 > 0.0
    lim = demo_report.summary["limit"]
    assert lim.jerk_rad_s3 is None
    assert lim.speed_violations is None
    assert (
        lim.segment_mean_deg["overall"]
        < demo_report.summary["pipeline"].segment_mean_deg["overall"]
    )


def test_settling_skips_the_start(op3: RobotConfig) -> None:
    motion = demo_motion(fps=125.0).frames(0, 100)
    settings = EvalRobotSettings(stride=10, settle_s=0.4, random_starts=1)
    clip = RobotEvaluator(op3, oracle_runner(op3), settings).score_motion(motion, "demo")
    assert clip.methods["pipeline"].angles.shape[0] == 5  # frames 50, 60, …, 90


def test_summary_weights_clips_by_duration(demo_report: EvalRobotReport) -> None:
    clip = demo_report.clips[0]
    longer = type(clip)(clip.name, 3.0 * clip.duration_s, clip.methods, clip.human_positions,
                        clip.robot_q)  # fmt: skip
    doubled = summarize([clip, longer])
    one = demo_report.summary
    for m in METHODS:
        assert doubled[m].segment_mean_deg["overall"] == pytest.approx(
            one[m].segment_mean_deg["overall"]
        )
    with pytest.raises(SourceError):
        summarize([])


def test_overrides_reach_the_config(op3: RobotConfig) -> None:
    cfg = with_retarget_overrides(op3, {"w_orientation": 0.0})
    assert cfg.retarget["w_orientation"] == 0.0
    assert cfg.joints == op3.joints


def test_validation_clips_filter_subjects(tmp_path: Path) -> None:
    for name in ("06/06_01.bvh", "06/06_02.bvh", "07/07_01.bvh"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    assert [n for n, _ in validation_clips(tmp_path, ["06"])] == ["06/06_01.bvh", "06/06_02.bvh"]
    with pytest.raises(SourceError):
        validation_clips(tmp_path, ["99"])


def test_a_folder_without_the_validation_subjects_is_scored_whole(tmp_path: Path) -> None:
    # Not the training data (no clip of the split's validation subjects 06, 08, 12): the
    # default scores every clip in it, whatever its subjects are called.
    for name in ("dance.bvh", "walk_01.bvh", "studio/jump.bvh"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    everything = ["dance.bvh", "studio/jump.bvh", "walk_01.bvh"]
    assert [n for n, _ in validation_clips(tmp_path)] == everything
    assert [n for n, _ in validation_clips(tmp_path, ["06", "08", "12"])] == everything
    with pytest.raises(SourceError):  # subjects asked for by name must exist
        validation_clips(tmp_path, ["06"])
    (tmp_path / "06").mkdir()
    (tmp_path / "06" / "06_01.bvh").write_text("")
    assert [n for n, _ in validation_clips(tmp_path)] == ["06/06_01.bvh"]


def test_real_clip_first_frames(op3: RobotConfig, shared_data_dir: Path, tmp_path: Path) -> None:
    clip = shared_data_dir / "mocap" / "08" / "08_01.bvh"
    if not clip.is_file():
        pytest.skip(f"{clip} not in the shared data")
    settings = EvalRobotSettings(max_frames=120, cache_dir=tmp_path)
    run = pipeline_runner(op3, "copy")
    report = evaluate_robot(op3, [("08/08_01.bvh", clip)], run, settings, model_name="copy")
    assert report.eval_frames == 11  # 1 s at 125 Hz, every 12th frame
    again = evaluate_robot(op3, [("08/08_01.bvh", clip)], run, settings, model_name="copy")
    assert list(tmp_path.glob("limit-*.npz"))  # the second run read the cached limit
    for a, b in zip(report.clips[0].robot_q["limit"], again.clips[0].robot_q["limit"], strict=True):
        np.testing.assert_array_equal(a, b)
    c = report.clips[0]
    limit = c.methods["limit"].angles.mean(axis=1)
    assert np.all(limit <= c.methods["pipeline"].angles.mean(axis=1) + 1e-9)
    assert np.all(limit <= c.methods["baseline"].angles.mean(axis=1) + 1e-9)
