"""``eval-robot --input 2d`` on a fixture clip: every input row, every view elevation, within
the limits; and the scorer itself (a robot copying the truth scores better than one standing)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.evaluation.keypoints_2d import (
    ELEVATIONS_DEG,
    Scorer,
    evaluate_2d,
    keypoints_of,
    markdown_2d,
    world_heading,
)
from robot_retarget.evaluation.robot.runner import oracle_runner
from robot_retarget.keypoints.lift import lift_keypoints
from robot_retarget.keypoints.synthetic import CLEAN
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.runtime.agnostic2d import load_keypoint_model

CLIP = Path(__file__).resolve().parents[1] / "fixtures" / "motion" / "tiny_walk.bvh"
TIME_LIMIT_S = 300


def test_every_row_and_elevation_within_limits() -> None:
    config = load_robot_config("op3")
    report = evaluate_2d(
        config,
        [("tiny_walk", CLIP)],
        "copy-scaled",
        load_keypoint_model(),
        clip_keypoint_model=load_keypoint_model(whole_clip=True),
    )
    assert report.keypoint_model == "agnostic2d_clip / agnostic2d"  # clip rows' / stream rows'
    for label in ("2d clip", "2d stream"):
        for e in ELEVATIONS_DEG:
            row = report.rows[f"{label} @ {e:g}°"]
            assert row.runs == 4  # four azimuths per elevation
            assert row.limit_violations == 0
            assert row.speed_violations == 0
            assert np.isfinite(row.direction_deg)
    assert report.rows["3d"].runs == 1
    for label in ("lifted, clip", "lifted, stream"):  # the keypoint model's own error
        assert report.rows[label].runs == 4 * len(ELEVATIONS_DEG)
        assert 0.0 < report.rows[label].direction_deg < 90.0
    table = markdown_2d(report)
    assert "| 2d stream @ 30° |" in table
    assert "| lifted, stream |" in table


def test_the_lifted_score_is_zero_for_the_truth_and_grows_with_a_bent_limb() -> None:
    scorer = Scorer(load_robot_config("op3"))
    truth = load_motion(CLIP)
    at_camera_rate = truth.resample(30.0)
    own = scorer.score_lifted(truth, at_camera_rate)
    assert own[0] == pytest.approx(0.0, abs=1e-6)
    assert own[2] == pytest.approx(at_camera_rate.num_frames / 30.0)
    q = np.array(at_camera_rate.local_quats)
    from robot_retarget.skeleton.canonical import Joint

    q[:, Joint.LeftForeArm] = [np.cos(0.5), np.sin(0.5), 0.0, 0.0]  # elbow bent 60° about x
    bent = type(at_camera_rate)(
        at_camera_rate.skeleton, q, at_camera_rate.root_pos, 30.0, at_camera_rate.source_path
    )
    worse = scorer.score_lifted(truth, bent)
    assert worse[0] > 1.0
    assert worse[1] > worse[0]  # a limb segment: the limb mean (8 of 9 segments) rises more


def test_world_heading_undoes_the_camera_azimuth() -> None:
    motion = load_motion(CLIP)
    seq_cam = VirtualCamera(1.0, 0.0, 4.0, 1000.0)
    seq = keypoints_of(motion, seq_cam, np.random.default_rng(0), CLEAN)
    lifted = lift_keypoints(seq, load_keypoint_model())
    turned = world_heading(lifted, seq_cam)
    np.testing.assert_allclose(turned.local_quats[:, 1:], lifted.local_quats[:, 1:])
    assert not np.allclose(turned.local_quats[:, 0], lifted.local_quats[:, 0])


def test_scorer_prefers_the_truth_to_standing_still() -> None:
    config = load_robot_config("op3")
    scorer = Scorer(config)
    truth = load_motion(CLIP)
    run = oracle_runner(config)(truth)
    assert run.root_quat is not None  # scored on its floating base
    good = scorer.score(truth, run.q, run.root_quat)
    still_q = np.repeat(np.asarray(config.init_pose)[None], len(run.q), 0)
    still = scorer.score(truth, still_q, run.root_quat)
    pitch = np.array([np.cos(0.25), 0.0, np.sin(0.25), 0.0])  # the base tipped 30° forward
    tipped = scorer.score(truth, run.q, np.tile(pitch, (len(run.q), 1)))
    assert good[0] < still[0]
    assert tipped[0] > good[0] + 5.0
    assert good[3] == 0
    assert good[4] == 0


def test_frames_without_a_body_hold_the_last_seen_pose() -> None:
    from robot_retarget.errors import MotionFormatError
    from robot_retarget.keypoints.sequence import KeypointSequence

    motion = load_motion(CLIP)
    seq = keypoints_of(
        motion, VirtualCamera(0.3, 0.1, 4.0, 1000.0), np.random.default_rng(0), CLEAN
    )
    valid = seq.valid.copy()
    valid[5:9] = False  # nobody in view for four frames
    hidden = KeypointSequence(seq.xy, seq.confidence, valid, seq.fps, "x")
    lifted = lift_keypoints(hidden, load_keypoint_model())
    for t in range(5, 9):
        np.testing.assert_array_equal(lifted.local_quats[t], lifted.local_quats[4])
    nobody = KeypointSequence(seq.xy, seq.confidence, np.zeros_like(valid), seq.fps, "x")
    with pytest.raises(MotionFormatError, match="nobody to follow"):
        lift_keypoints(nobody, load_keypoint_model())


def test_the_clip_rows_use_the_clip_model_and_stream_rows_the_causal_one() -> None:
    """Lifting the clip rows with the causal model instead changes only the clip rows."""
    config = load_robot_config("op3")
    both = [
        evaluate_2d(config, [("tiny_walk", CLIP)], "copy-scaled", load_keypoint_model(),
                    clip_keypoint_model=clip, max_frames=60)
        for clip in (None, load_keypoint_model(whole_clip=True))
    ]  # fmt: skip
    assert both[0].keypoint_model == "agnostic2d"
    for key in ("lifted, stream", "2d stream"):
        assert both[0].rows[key].direction_deg == both[1].rows[key].direction_deg
    for key in ("lifted, clip", "2d clip"):
        assert both[0].rows[key].direction_deg != both[1].rows[key].direction_deg


def test_eval_robot_refuses_keypoint_models_it_cannot_use(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The keypoint options need --input 2d; a centred model cannot lift the stream rows."""
    from robot_retarget.cli.main import main
    from robot_retarget.runtime.agnostic2d import SHIPPED_CLIP_KEYPOINT_MODEL

    for option in ("--keypoint-model", "--clip-keypoint-model"):
        with pytest.raises(SystemExit, match="add --input 2d"):
            main(["eval-robot", option, "agnostic2d"])
    with pytest.raises(SystemExit, match="add --input 2d"):
        main(["eval-robot", "--no-image-planes"])
    (tmp_path / "99").mkdir()
    (tmp_path / "99" / "99_01.bvh").write_bytes(CLIP.read_bytes())
    args = ["eval-robot", "--input", "2d", "--data", str(tmp_path)]
    assert main([*args, "--keypoint-model", str(SHIPPED_CLIP_KEYPOINT_MODEL)]) == 1
    assert "looks ahead (centered)" in capsys.readouterr().err
    # Each row set names the model that lifted it: a report says how to reproduce it.
    assert main([*args, "--model", "copy-scaled", "--max-frames", "40", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["keypoint_model"] == "agnostic2d_clip / agnostic2d"
    assert report["image_planes"] is True
    assert report["rows"]["2d clip"]["limit_violations"] == 0
    # Without the image's planes both row sets change.
    assert main([*args, "--model", "copy-scaled", "--max-frames", "40", "--json",
                 "--no-image-planes"]) == 0  # fmt: skip
    plain = json.loads(capsys.readouterr().out)
    assert plain["image_planes"] is False
    for key in ("2d clip", "lifted, clip", "2d stream", "lifted, stream"):
        assert plain["rows"][key] != report["rows"][key]
    # --keypoint-model alone lifts both row sets.
    flags = ["--model", "copy-scaled", "--max-frames", "40", "--json"]
    assert main([*args, *flags, "--keypoint-model", "agnostic2d"]) == 0
    assert json.loads(capsys.readouterr().out)["keypoint_model"] == "agnostic2d"
