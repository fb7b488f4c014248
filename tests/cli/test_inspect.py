"""``inspect``: text and JSON reports, unreadable files, options."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from robot_retarget.cli.main import main

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
DATA = Path(
    os.environ.get(
        "ROBOT_RETARGET_DATA", Path(__file__).resolve().parents[2].parent / "shared" / "data"
    )
)


def test_text_report_for_asf_and_unknown_names(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["inspect", str(FIXTURES / "asf_names.bvh"), str(FIXTURES / "unknown_names.bvh")])
    out = capsys.readouterr().out
    assert rc == 0
    assert "family:      CMU ASF" in out
    assert "family:      automatic (topology)" in out
    assert "LeftHand←lwrist" in out
    assert "Hips←pelvis_j" in out
    assert "mapped:      22/22" in out
    assert "unit:        cmu (height 1.710 m" in out
    assert "frames:      16 at 30 fps (0.533 s)" in out


def test_real_clip_reports_tpose_and_synthesised_joints(capsys: pytest.CaptureFixture[str]) -> None:
    mb2 = DATA / "mocap" / "02" / "02_01.bvh"
    daz = DATA / "mocap" / "13" / "13_11.bvh"
    if not (mb2.is_file() and daz.is_file()):
        pytest.skip(f"shared mocap clips not found under {DATA}: set ROBOT_RETARGET_DATA")
    assert main(["inspect", str(mb2), str(daz)]) == 0
    out = capsys.readouterr().out
    assert "CMU MotionBuilder" in out
    assert "T-pose dropped: yes (1 frame(s))" in out
    assert "frames:      343 at 120 fps" in out
    assert "synthesised: Spine1, LeftToeBase, RightToeBase" in out
    assert "unit:        cm" in out


def test_unreadable_file_fails_but_others_are_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "missing.bvh"
    rc = main(
        [
            "inspect",
            str(FIXTURES / "malformed" / "truncated.bvh"),
            str(FIXTURES / "tiny_walk.bvh"),
            str(missing),
        ]
    )
    captured = capsys.readouterr()
    assert rc == 1
    assert "tiny_walk.bvh" in captured.out
    errors = captured.err.strip().splitlines()
    assert len(errors) == 2
    assert "truncated.bvh, line 21" in errors[0]
    assert "missing.bvh" in errors[1]


def test_json_output(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["inspect", "--json", str(FIXTURES / "tiny_walk.bvh"), str(FIXTURES / "mixamo.bvh")])
    assert rc == 0
    reports = json.loads(capsys.readouterr().out)
    assert [r["family"] for r in reports] == ["CMU MotionBuilder", "Mixamo"]
    walk = reports[0]
    assert walk["frames"] == 24
    assert walk["file_frames"] == 25
    assert walk["tpose_dropped"] is True
    assert walk["unit"] == "cmu"
    assert walk["mapping"]["Neck"] == "Neck1"
    assert walk["synthesized"] == []
    assert walk["height_m"] == pytest.approx(1.71, abs=0.01)


def test_options_keep_tpose_and_unit(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(
        ["inspect", "--json", "--keep-tpose", "--unit", "cm", str(FIXTURES / "tiny_walk.bvh")]
    )
    assert rc == 0
    (report,) = json.loads(capsys.readouterr().out)
    assert report["frames"] == 25
    assert report["tpose_dropped"] is False
    assert report["unit"] == "cm"
    assert report["height_m"] == pytest.approx(1.71 / 5.644, rel=0.01)


def test_json_with_a_failure_still_lists_the_others(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(["inspect", "--json", str(tmp_path / "nope.bvh"), str(FIXTURES / "asf_names.bvh")])
    captured = capsys.readouterr()
    assert rc == 1
    missing, clip = json.loads(captured.out)  # in the order asked, the failure with its error
    assert missing == {
        "file": str(tmp_path / "nope.bvh"),
        "error": f"{tmp_path / 'nope.bvh'}: cannot read the file: No such file or directory",
    }
    assert clip["family"] == "CMU ASF"
    assert captured.err.count("\n") == 1


def test_a_folder_is_every_bvh_under_it_sorted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    clips = tmp_path / "clips"
    (clips / "sub").mkdir(parents=True)
    shutil.copy(FIXTURES / "mixamo.bvh", clips / "b.bvh")
    shutil.copy(FIXTURES / "tiny_walk.bvh", clips / "a.BVH")
    shutil.copy(FIXTURES / "asf_names.bvh", clips / "sub" / "c.bvh")
    (clips / "notes.txt").write_text("not a clip")
    (tmp_path / "empty").mkdir()
    rc = main(["inspect", "--json", str(clips), str(tmp_path / "empty")])
    captured = capsys.readouterr()
    assert rc == 1  # the empty folder
    *reports, empty = json.loads(captured.out)
    assert empty["file"] == str(tmp_path / "empty")
    assert empty["error"].endswith("empty: no .bvh files in this folder")
    assert [Path(r["file"]).relative_to(clips).as_posix() for r in reports] == [
        "a.BVH",
        "b.bvh",
        "sub/c.bvh",
    ]
    assert [r["family"] for r in reports] == ["CMU MotionBuilder", "Mixamo", "CMU ASF"]
    errors = captured.err.strip().splitlines()
    assert len(errors) == 1
    assert "empty: no .bvh files in this folder" in errors[0]


def test_reports_how_a_skeleton_aware_model_reads_the_file(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["inspect", "--json", str(FIXTURES / "tiny_walk.bvh")]) == 0
    armatures = json.loads(capsys.readouterr().out)[0]["armatures"]
    assert armatures["skeleton"] == "CMU MotionBuilder-25j"
    assert armatures["kept"] == len(armatures["names"]) == 24
    assert "LHipJoint" in armatures["names"]  # a joint the canonical skeleton folds away
    assert main(["inspect", str(FIXTURES / "tiny_walk.bvh")]) == 0
    assert "own skeleton (SAN): CMU MotionBuilder-25j, 24 joints" in capsys.readouterr().out
