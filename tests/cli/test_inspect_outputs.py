"""``inspect`` of a robot trajectory and of 2D keypoint input."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robot_retarget.cli.main import main
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.loader import load_robot_config

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"


@pytest.fixture(scope="module")
def led_trajectory(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("inspect") / "walk.npz"
    clip = FIXTURES / "motion" / "tiny_walk.bvh"
    assert main(["convert", str(clip), "--out", str(out), "--lead-in", "--fps", "50"]) == 0
    return out


def _report(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict[str, Any], str]:
    capsys.readouterr()
    code = main(["inspect", *argv, "--json"])
    out, err = capsys.readouterr()
    reports = json.loads(out)
    return code, (reports[0] if reports else {}), err


def test_a_converted_trajectory_tells_its_robot_lead_in_base_and_limits(
    led_trajectory: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    traj = RobotTrajectory.read(led_trajectory)
    code, info, _ = _report(capsys, str(led_trajectory))
    assert code == 0
    lead = round(-traj.t0 * traj.fps)
    assert (info["kind"], info["robot"], info["frames"]) == (
        "robot trajectory",
        "op3",
        traj.num_frames,
    )
    assert info["lead_in_frames"] == lead > 0
    assert info["limits_ok"] is True
    assert info["base"] is True
    low, high = info["lead_in_lowest_foot_m"]
    assert -1e-9 < low <= high < 1e-3  # the lead-in stands on the floor
    assert main(["inspect", str(led_trajectory)]) == 0
    text = capsys.readouterr().out
    assert f"{lead} of them a lead-in" in text
    assert "limits:      respected" in text


def test_a_trajectory_over_the_limits_says_by_how_much(
    led_trajectory: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    traj = RobotTrajectory.read(led_trajectory)
    op3 = load_robot_config("op3")
    q = traj.q.copy()
    q[-1, 0] = op3.upper[0] + 0.2  # one joint past its limit in the last row
    bad = tmp_path / "bad.csv"
    RobotTrajectory(traj.joint_names, q, traj.fps, t0=traj.t0).write(bad)
    code, info, _ = _report(capsys, str(bad))
    assert code == 0  # a report, not a failure to read
    assert info["limits_ok"] is False
    assert info["position_excess_rad"] == pytest.approx(0.2, abs=1e-6)
    assert info["base"] is False
    assert main(["inspect", str(bad)]) == 0
    assert "limits:      EXCEEDED (position by 0.2000 rad" in capsys.readouterr().out


def test_a_robot_that_does_not_fit_is_an_error_and_an_unknown_one_is_said(
    led_trajectory: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = _report(capsys, str(led_trajectory), "--robot", "poppy_humanoid")
    assert code == 1
    assert (
        "the trajectory's joints are not poppy_humanoid's ('r_sho_pitch' is not one of them; 25 "
        "of poppy_humanoid's missing, 20 unknown): pass the robot it was converted for with "
        "--robot" in err
    )
    odd = tmp_path / "odd.json"
    RobotTrajectory(("a", "b"), np.zeros((3, 2)), 30.0).write(odd)
    code, info, _ = _report(capsys, str(odd))
    assert code == 0
    assert info["robot"] is None
    assert "pass --robot" in info["robot_why"]


@pytest.mark.parametrize(
    ("name", "frames", "missing"),
    [("coco17.jsonl", 3, 0.020), ("mediapipe_pose.json", 3, 0.373), ("openpose_body25", 3, 0.059)],
)
def test_keypoint_input_tells_frames_image_and_what_is_missing(
    name: str, frames: int, missing: float, capsys: pytest.CaptureFixture[str]
) -> None:
    code, info, _ = _report(capsys, str(FIXTURES / "keypoints" / name))
    assert code == 0
    assert info["kind"] == "2D keypoints"
    assert info["frames"] == frames
    assert info["missing_share"] == pytest.approx(missing, abs=1e-3)


def test_a_broken_keypoint_file_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "pose.json"
    bad.write_text("{bad", encoding="utf-8")
    assert main(["inspect", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {bad}: not a JSON document")
    assert len(err.strip().splitlines()) == 1


def test_a_model_runtime_is_named_as_one(capsys: pytest.CaptureFixture[str]) -> None:
    from robot_retarget.runtime.loader import shipped_runtimes

    runtime = shipped_runtimes()["default"]
    assert main(["inspect", str(runtime)]) == 1
    err = capsys.readouterr().err
    assert "a model's numpy runtime (written by train or export), not a trajectory" in err


def test_a_robot_bvh_is_told_as_the_robot_s_not_mapped_as_a_human(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """convert --bvh-out's file: its robot, frames and base as the trajectory beside it (it was
    refused as a human skeleton that lacks Hips, Spine, …)."""
    clip = FIXTURES / "motion" / "tiny_walk.bvh"
    out, bvh = tmp_path / "w.npz", tmp_path / "w.bvh"
    assert main(["convert", str(clip), "--robot", "poppy_humanoid", "--out", str(out),
                 "--bvh-out", str(bvh)]) == 0  # fmt: skip
    traj = RobotTrajectory.read(out)
    code, info, err = _report(capsys, str(bvh))
    assert (code, err) == (0, "")
    assert (info["kind"], info["robot"], info["frames"]) == (
        "robot BVH",
        "poppy_humanoid",
        traj.num_frames,
    )
    assert info["fps"] == pytest.approx(traj.fps)
    assert traj.root_pos is not None
    np.testing.assert_allclose(
        info["base_height_m"], [traj.root_pos[:, 2].min(), traj.root_pos[:, 2].max()], atol=1e-6
    )
    path = np.linalg.norm(np.diff(traj.root_pos[:, :2], axis=0), axis=1).sum()
    assert info["base_path_m"] == pytest.approx(path, abs=1e-5)
    # --robot naming another robot: not its links, so it is read as a motion clip (Poppy's
    # skeleton maps onto the human one by its topology)
    code, info, _ = _report(capsys, str(bvh), "--robot", "op3")
    assert (code, info["family"]) == (0, "automatic (topology)")
    # a human clip is still one, whatever --robot says
    code, info, _ = _report(capsys, str(clip), "--robot", "op3")
    assert (code, info["family"]) == (0, "CMU MotionBuilder")


def test_a_robot_config_is_checked_and_summarised(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """inspect my_robot.yaml had said 'not a BVH file'; it now reads it as convert does."""
    config = load_robot_config("op3")
    path = Path(config.source_path or "")
    code, info, err = _report(capsys, str(path))
    assert (code, err) == (0, "")
    assert (info["kind"], info["robot"]) == ("robot config", "op3")
    assert [j["name"] for j in info["joints"]] == list(config.joint_names)
    assert info["joints"][0]["limits_deg"] == pytest.approx(
        np.degrees([config.lower[0], config.upper[0]])
    )
    assert sum(len(b["servo_ids"]) for b in info["buses"]) == config.num_joints
    assert len(info["bones"]) == len(config.bones)
    assert main(["inspect", str(path)]) == 0
    assert "robot config, valid" in capsys.readouterr().out
    bad = tmp_path / "op3.yaml"
    bad.write_text(path.read_text().replace("retarget:\n", "retarget:\n  w_orientaton: 0.1\n", 1))
    code, info, err = _report(capsys, str(bad))
    assert code == 1
    assert "retarget.w_orientaton" in info["error"]
    assert "did you mean 'w_orientation'" in err


def test_a_bvh_that_is_no_human_says_how_to_read_a_robot_s_own(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot BVH of a robot that is not bundled maps onto no human: the error says --robot
    reads it (it said only to rename the joints after a human naming family)."""
    bvh = tmp_path / "mine.bvh"
    bvh.write_text(
        "HIERARCHY\nROOT base_link\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition "
        "Zposition Zrotation Xrotation Yrotation\n JOINT arm_link\n {\n  OFFSET 0 0.1 0\n  "
        "CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 0.1 0\n  }\n "
        "}\n}\nMOTION\nFrames: 1\nFrame Time: 0.02\n0 0.3 0 0 0 0 0 0 0\n"
    )
    code, _, err = _report(capsys, str(bvh))
    assert code == 1
    assert "pass --robot with its config" in err
