"""``convert`` from 2D keypoints: a COCO-17 file made from a known 3D motion converts within the
limits and follows the performer; an OpenPose folder converts; a broken file is reported."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.cli import convert_cmd
from robot_retarget.evaluation.keypoints_2d import Scorer, keypoints_of
from robot_retarget.keypoints.synthetic import EstimatorNoise
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import check_limits
from robot_retarget.robot.loader import load_robot_config

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "keypoints"
TIME_LIMIT_S = 180


def _run(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    convert_cmd.configure(parser)
    return convert_cmd.run(parser.parse_args(list(argv)))


def _write_jsonl(path: Path, px: np.ndarray, conf: np.ndarray) -> None:
    with path.open("w") as fh:
        for t in range(px.shape[0]):
            kp = np.concatenate([np.nan_to_num(px[t]), conf[t][:, None]], axis=1)
            fh.write(json.dumps({"frame": t, "people": [{"keypoints": kp.tolist()}]}) + "\n")


def test_projected_demo_motion_converts_and_follows_the_performer(tmp_path: Path) -> None:
    truth = demo_motion(fps=30.0).frames(0, 150)
    camera = VirtualCamera(math.radians(30.0), math.radians(10.0), 4.0, 1000.0)
    seq = keypoints_of(truth, camera, np.random.default_rng(0), EstimatorNoise())
    src = tmp_path / "performer.jsonl"
    _write_jsonl(src, seq.xy, seq.confidence)
    out = tmp_path / "performer_op3.npz"
    assert _run(str(src), "--robot", "op3", "--out", str(out)) == 0
    traj = RobotTrajectory.read(out)
    config = load_robot_config("op3")
    assert check_limits(config, traj.q, 1.0 / traj.fps).ok
    scorer = Scorer(config)
    base = np.asarray(traj.root_quat)  # on the trajectory's floating base
    followed = scorer.score(truth, np.asarray(traj.q), base)[0]
    held = scorer.score(truth, np.repeat(np.asarray(config.init_pose)[None], len(traj.q), 0), base)[
        0
    ]
    # The robot follows the performer seen only in 2D far better than standing still.
    assert followed < 0.6 * held, (followed, held)


def test_openpose_folder_converts(tmp_path: Path) -> None:
    out = tmp_path / "op.npz"
    assert _run(str(FIXTURES / "openpose_body25"), "--robot", "op3", "--out", str(out)) == 0
    traj = RobotTrajectory.read(out)
    assert check_limits(load_robot_config("op3"), traj.q, 1.0 / traj.fps).ok


def test_broken_keypoint_file_is_reported(tmp_path: Path, capsys: object) -> None:
    src = tmp_path / "broken.jsonl"
    src.write_text('{"people": []}\n{"people": [{"keypoints": [1, 2, 3]}]}\n')
    assert _run(str(src), "--robot", "op3", "--out", str(tmp_path / "b.npz")) == 1
    err = capsys.readouterr().err  # type: ignore[attr-defined]
    assert "broken.jsonl" in err
    assert "frame 1" in err
    assert not (tmp_path / "b.npz").exists()


def test_convert_lifts_with_the_centred_model_unless_told(tmp_path: Path) -> None:
    """convert's default keypoint model is the shipped centred one (it sees ahead of each
    frame); ``--keypoint-model agnostic2d`` lifts with the causal one stream runs."""
    from robot_retarget.keypoints.lift import lift_keypoints, load_keypoint_motion
    from robot_retarget.runtime.agnostic2d import load_keypoint_model
    from robot_retarget.sources.keypoints import load_keypoints

    folder = FIXTURES / "openpose_body25"
    seq = load_keypoints(folder)
    for name, whole_clip in ((None, True), ("agnostic2d", False)):
        lifted = load_keypoint_motion(folder, model=name).motion
        expected = lift_keypoints(seq, load_keypoint_model(whole_clip=whole_clip))
        np.testing.assert_array_equal(lifted.local_quats, expected.local_quats)
    outs = [tmp_path / "clip.npz", tmp_path / "causal.npz"]
    assert _run(str(folder), "--robot", "op3", "--out", str(outs[0])) == 0
    flags = ("--keypoint-model", "agnostic2d")
    assert _run(str(folder), "--robot", "op3", "--out", str(outs[1]), *flags) == 0
    q = [np.asarray(RobotTrajectory.read(p).q) for p in outs]
    assert not np.allclose(q[0], q[1])


def test_convert_turns_bones_into_the_image_planes_unless_told(tmp_path: Path) -> None:
    """By default convert turns the lifted bones into the planes the keypoints put them in;
    ``--no-image-planes`` keeps the keypoint model's answer."""
    from robot_retarget.keypoints.lift import lift_keypoints, load_keypoint_motion
    from robot_retarget.runtime.agnostic2d import load_keypoint_model
    from robot_retarget.sources.keypoints import load_keypoints

    folder = FIXTURES / "openpose_body25"
    model = load_keypoint_model(whole_clip=True)
    seq = load_keypoints(folder)
    for planes in (True, False):
        lifted = load_keypoint_motion(folder, image_planes=planes).motion
        expected = lift_keypoints(seq, model, image_planes=planes)
        np.testing.assert_array_equal(lifted.local_quats, expected.local_quats)
    outs = [tmp_path / "planes.npz", tmp_path / "plain.npz"]
    assert _run(str(folder), "--robot", "op3", "--out", str(outs[0])) == 0
    assert _run(str(folder), "--robot", "op3", "--out", str(outs[1]), "--no-image-planes") == 0
    trajs = [RobotTrajectory.read(p) for p in outs]
    assert not np.allclose(trajs[0].q, trajs[1].q)
    config = load_robot_config("op3")
    assert all(check_limits(config, t.q, 1.0 / t.fps).ok for t in trajs)


def test_convert_reports_the_camera_it_estimated(tmp_path: Path, capsys: object) -> None:
    """The image's planes need a camera: convert estimates one per clip and says so. Seen from
    higher, the built-in routine's camera is estimated higher (the routine is not a CMU
    performer: the estimates run 7–10° low here)."""
    from robot_retarget.keypoints.lift import load_keypoint_motion

    truth = demo_motion(fps=30.0).frames(0, 150)
    estimates = []
    for elevation in (0.0, 10.0, 30.0):
        camera = VirtualCamera(math.radians(30.0), math.radians(elevation), 4.0, 1000.0)
        seq = keypoints_of(truth, camera, np.random.default_rng(0), EstimatorNoise())
        src = tmp_path / f"seen_from_{elevation:g}.jsonl"
        _write_jsonl(src, seq.xy, seq.confidence)
        lifted = load_keypoint_motion(src)
        assert lifted.camera is not None
        estimates.append(math.degrees(lifted.camera.elevation_rad))
        assert abs(estimates[-1] - elevation) < 12.0
    assert estimates == sorted(estimates)
    assert _run(str(src), "--robot", "op3", "--out", str(tmp_path / "o.npz")) == 0
    err = capsys.readouterr().err  # type: ignore[attr-defined]
    assert f"camera estimated at {estimates[-1]:.0f}° elevation" in err
    assert load_keypoint_motion(src, image_planes=False).camera is None


def test_a_keypoint_model_that_does_not_exist_is_named_before_any_clip(tmp_path: Path) -> None:
    import pytest

    from robot_retarget.errors import ModelLoadError

    with pytest.raises(ModelLoadError, match="no keypoint model 'nosuch': not agnostic2d"):
        _run(
            str(FIXTURES / "openpose_body25"), "--out", str(tmp_path / "x"),
            "--keypoint-model", "nosuch",
        )  # fmt: skip
    assert not (tmp_path / "x").exists()


def test_a_folder_of_clips_says_which_keypoint_files_it_leaves(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    folder = tmp_path / "mixed"
    folder.mkdir()
    shutil.copy(Path(__file__).resolve().parents[1] / "fixtures" / "motion" / "tiny_walk.bvh",
                folder / "walk.bvh")  # fmt: skip
    (folder / "cam.jsonl").write_text("{}\n")
    assert _run(str(folder), "--out", str(tmp_path / "out")) == 0
    err = capsys.readouterr().err
    assert "note: 1 .json/.jsonl file(s) under" in err
    assert "(cam.jsonl): a folder's conversion takes its .bvh clips" in err
