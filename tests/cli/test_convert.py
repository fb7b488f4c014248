"""``convert``: shared clips to NPZ / CSV / JSON within limits, folders, failures, --force."""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.cli import convert_cmd
from robot_retarget.cli.output_paths import OutputPathError
from robot_retarget.errors import ModelLoadError, MotionFormatError
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import check_limits
from robot_retarget.robot.loader import load_robot_config

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
TIME_LIMIT_S = 120


def _run(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    convert_cmd.configure(parser)
    return convert_cmd.run(parser.parse_args(list(argv)))


@pytest.mark.data
@pytest.mark.parametrize("suffix", [".npz", ".csv", ".json"])
def test_shared_clip_to_each_format(shared_data_dir: Path, tmp_path: Path, suffix: str,
                                    capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    clip = shared_data_dir / "mocap" / "02" / "02_05.bvh"
    out = tmp_path / f"boxing{suffix}"
    assert _run(str(clip), "--robot", "op3", "--out", str(out), "--max-frames", "150") == 0
    traj = RobotTrajectory.read(out)
    config = load_robot_config("op3")
    assert traj.joint_names == config.joint_names
    assert traj.fps == config.control_rate_hz
    assert traj.root_pos is not None
    assert traj.root_quat is not None
    assert traj.frame_ms is not None
    assert traj.num_frames == 156  # 150 frames at 120 fps → 1.24 s at 125 Hz
    atol = 1e-12 if suffix == ".npz" else 1e-9  # text formats round the last digit
    assert np.all(traj.q >= config.lower - atol)
    assert np.all(traj.q <= config.upper + atol)
    assert check_limits(config, traj.q, 1 / traj.fps).velocity_excess_rad < 1e-9
    summary = capsys.readouterr().out
    assert "limits respected" in summary
    assert "safety clipped 0 commands" in summary
    assert "0 solver fallbacks" in summary


@pytest.mark.data
def test_daz_naming_family(shared_data_dir: Path, tmp_path: Path) -> None:
    clips = sorted((shared_data_dir / "mocap" / "12").glob("*.bvh"))
    if not clips:
        pytest.skip("no DAZ-converted clips in the shared data (subject 12)")
    out = tmp_path / "daz.npz"
    assert _run(str(clips[0]), "--out", str(out), "--max-frames", "40", "--fps", "30") == 0
    assert RobotTrajectory.read(out).fps == 30.0


@pytest.mark.parametrize("name", ["tiny_walk", "asf_names", "mixamo", "z_up", "crlf_tabs"])
def test_every_naming_family_of_the_fixtures(name: str, tmp_path: Path) -> None:
    out = tmp_path / f"{name}.json"
    assert _run(str(FIXTURES / f"{name}.bvh"), "--out", str(out), "--fps", "30") == 0
    traj = RobotTrajectory.read(out)
    assert traj.num_frames > 5
    assert check_limits(load_robot_config("op3"), traj.q, 1 / 30).ok


def test_folder_keeps_structure_and_survives_a_bad_clip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "in"
    (src / "walks").mkdir(parents=True)
    shutil.copy(FIXTURES / "tiny_walk.bvh", src / "walks" / "a.bvh")
    shutil.copy(FIXTURES / "mixamo.bvh", src / "b.bvh")
    (src / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    out = tmp_path / "out"
    rc = _run(str(src), "--out", str(out), "--format", "csv", "--fps", "30",
              "--bvh-out", str(tmp_path / "bvh"))  # fmt: skip
    assert rc == 1
    assert (out / "walks" / "a.csv").is_file()
    assert (out / "b.csv").is_file()
    assert not (out / "broken.csv").exists()
    assert (tmp_path / "bvh" / "walks" / "a.bvh").is_file()
    text = capsys.readouterr()
    assert "FAILED" in text.out
    assert "broken.bvh" in text.err
    assert "2 of 3 clips" in text.out
    # The failed clip's path leads its error once, though the error names the file itself.
    broken = str(src / "broken.bvh")
    assert text.err.count(broken) == 1
    assert f"FAILED {broken}, line 4: " in text.out


def test_a_lone_failed_clip_says_its_error_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One clip that fails: its error line, and no summary repeating it (nor one claiming
    anything about limits)."""
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    assert _run(str(bad), "--out", str(tmp_path / "x.npz")) == 1
    text = capsys.readouterr()
    assert (text.out + text.err).count(str(bad)) == 1
    assert "summary:" not in text.out
    assert "limits respected" not in text.out
    assert not (tmp_path / "x.npz").exists()


def test_existing_output_needs_force(tmp_path: Path) -> None:
    out = tmp_path / "t.npz"
    clip = str(FIXTURES / "tiny_walk.bvh")
    assert _run(clip, "--out", str(out), "--fps", "30") == 0
    stamp = out.stat().st_mtime_ns
    with pytest.raises(OutputPathError, match="already exists; pass --force"):
        _run(clip, "--out", str(out), "--fps", "30")
    assert out.stat().st_mtime_ns == stamp
    assert _run(clip, "--out", str(out), "--fps", "30", "--force") == 0


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.usefixtures("no_work")
def test_an_output_never_replaces_an_input(tmp_path: Path) -> None:
    src = tmp_path / "clips"
    (src / "walks").mkdir(parents=True)
    shutil.copy(FIXTURES / "tiny_walk.bvh", src / "walks" / "a.bvh")
    shutil.copy(FIXTURES / "mixamo.bvh", src / "b.bvh")
    before = _snapshot(src)
    clip = src / "b.bvh"
    with pytest.raises(OutputPathError, match="is the input") as e:
        _run(str(clip), "--out", str(tmp_path / "b.npz"), "--bvh-out", str(clip), "--force")
    assert (e.value.option, e.value.path, e.value.other) == ("--bvh-out", str(clip), str(clip))
    with pytest.raises(OutputPathError, match="is the input"):  # the folder into itself
        _run(str(src), "--out", str(src), "--bvh-out", str(src), "--force")
    assert _snapshot(src) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clips"]


@pytest.mark.usefixtures("no_work")
def test_no_two_outputs_on_one_path(tmp_path: Path) -> None:
    clip = str(FIXTURES / "tiny_walk.bvh")
    out = tmp_path / "t.npz"
    with pytest.raises(OutputPathError, match="also the output of --out"):
        _run(clip, "--out", str(out), "--bvh-out", str(out))
    src = tmp_path / "in"
    src.mkdir()
    shutil.copy(FIXTURES / "tiny_walk.bvh", src / "walk.bvh")
    shutil.copy(FIXTURES / "mixamo.bvh", src / "walk.BVH")  # both would be walk.npz
    with pytest.raises(OutputPathError, match=r"walk\.npz: is also the output of --out"):
        _run(str(src), "--out", str(tmp_path / "out"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


@pytest.mark.usefixtures("no_work")
def test_unwritable_or_missing_folders_are_refused_before_work(
    tmp_path: Path, read_only_dir: Path
) -> None:
    clip = str(FIXTURES / "tiny_walk.bvh")
    out = tmp_path / "t.npz"
    with pytest.raises(OutputPathError, match=r"--preview .*not writable"):
        _run(clip, "--out", str(out), "--preview", str(read_only_dir / "t.gif"))
    with pytest.raises(OutputPathError, match=r"--out .*no such folder"):
        _run(clip, "--out", str(tmp_path / "missing" / "t.npz"))
    with pytest.raises(OutputPathError, match=r"--bvh-out .*not writable"):
        _run(str(FIXTURES), "--out", str(tmp_path / "o"), "--bvh-out", str(read_only_dir / "b"))
    assert list(tmp_path.iterdir()) == [read_only_dir]


def test_a_failed_output_leaves_no_partial_outputs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def broken_renderer(path: Path, *args: object, **kwargs: object) -> Path:
        Path(path).write_bytes(b"GIF89a half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("robot_retarget.render.preview.render_preview", broken_renderer)
    clip = str(FIXTURES / "tiny_walk.bvh")
    rc = _run(clip, "--out", str(tmp_path / "t.npz"), "--bvh-out", str(tmp_path / "t.bvh"),
              "--preview", str(tmp_path / "t.gif"), "--fps", "30")  # fmt: skip
    assert rc == 1
    assert list(tmp_path.iterdir()) == []  # neither the trajectory nor the BVH, no temporaries
    assert "--preview" in capsys.readouterr().err


def test_preview_and_robot_bvh(tmp_path: Path) -> None:
    out = tmp_path / "t.npz"
    gif = tmp_path / "t.gif"
    bvh = tmp_path / "robot.bvh"
    clip = str(FIXTURES / "tiny_walk.bvh")
    assert _run(clip, "--out", str(out), "--preview", str(gif), "--bvh-out", str(bvh)) == 0
    assert gif.stat().st_size > 1000
    assert bvh.read_text().startswith("HIERARCHY\nROOT body_link")


def test_bad_arguments(tmp_path: Path) -> None:
    clip = str(FIXTURES / "tiny_walk.bvh")
    with pytest.raises(OutputPathError, match="must end in"):
        _run(clip, "--out", str(tmp_path / "t.txt"))
    with pytest.raises(MotionFormatError, match="no such file"):
        _run(str(tmp_path / "missing.bvh"), "--out", str(tmp_path / "t.npz"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(MotionFormatError, match=r"no \.bvh files"):
        _run(str(tmp_path / "empty"), "--out", str(tmp_path / "o"))
    with pytest.raises(ModelLoadError, match="'copy-scaled' has no foot lock") as err:
        _run(clip, "--out", str(tmp_path / "t.npz"), "--model", "copy-scaled", "--foot-lock")
    assert err.value.model == "copy-scaled"
    assert not (tmp_path / "t.npz").exists()


def test_files_that_are_not_models_say_what_to_pass(tmp_path: Path) -> None:
    """A clip or a trajectory given as --model: what the file is, and what --model takes (not
    torch's unpickling error, nor a missing __meta__ entry)."""
    clip = str(FIXTURES / "tiny_walk.bvh")
    trajectory = RobotTrajectory(("a", "b"), np.zeros((3, 2)), 125.0).write(tmp_path / "t.npz")
    takes = "a model name such as default, a runtime .npz written by export, a .pt checkpoint"
    out = str(tmp_path / "o.npz")
    for model, kind in ((clip, "a BVH motion clip"), (str(trajectory), "a robot trajectory")):
        with pytest.raises(ModelLoadError, match=f"{kind}.*, not a model: give --model") as err:
            _run(clip, "--out", out, "--model", model)
        assert takes in str(err.value)
        assert "Unpickling" not in str(err.value)
        assert "__meta__" not in str(err.value)
        assert err.value.path == model
    with pytest.raises(ModelLoadError, match=r"or pass a runtime \.npz written by export, a \.pt"):
        _run(clip, "--out", out, "--model", "nosuch")
    cut = tmp_path / "cut.npz"  # a runtime cut off in the copy: an error, not a traceback
    cut.write_bytes(trajectory.read_bytes()[:300])
    with pytest.raises(ModelLoadError, match=r"not a runtime \.npz file"):
        _run(clip, "--out", out, "--model", str(cut))
    assert not (tmp_path / "o.npz").exists()


def test_model_help_says_what_the_default_is() -> None:
    parser = argparse.ArgumentParser()
    convert_cmd.configure(parser)
    action = next(a for a in parser._actions if "--model" in a.option_strings)
    assert "the default)" not in str(action.help)
    assert "omitted: the shipped model 'default'" in str(action.help)
    assert "runtime .npz" in str(action.help)


def test_progress_counts_solves_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A clip's bar counts the solves of its frames at the output rate, once per branch-choice
    pass and once for the file: the header says so, and the count is labelled."""
    from robot_retarget.pipeline.limb_branch_choice import STARTS

    out = tmp_path / "t.npz"
    assert _run(str(FIXTURES / "tiny_walk.bvh"), "--out", str(out)) == 0
    frames = RobotTrajectory.read(out).num_frames  # at the control rate, not the clip's 30 fps
    err = capsys.readouterr().err
    assert f"progress counts solves, {STARTS + 1} per frame at 125 Hz" in err
    total = (STARTS + 1) * frames
    assert f"({total}/{total} solves)" in err
    assert _run(str(FIXTURES / "tiny_walk.bvh"), "--out", str(out), "--force",
                "--stream-branches", "--fps", "30") == 0  # fmt: skip
    err = capsys.readouterr().err
    frames = RobotTrajectory.read(out).num_frames
    assert "progress counts solves, one per frame at 30 Hz" in err
    assert f"({frames}/{frames} solves)" in err


def test_progress_bar_writes_only_the_final_line_to_a_file() -> None:
    import io

    buf = io.StringIO()
    bar = convert_cmd.ProgressBar("clip", width=10, stream=buf)
    for k in range(1, 101):
        bar(k, 100)
    assert buf.getvalue() == "clip [##########] 100% (100/100)\n"
    buf = io.StringIO()
    convert_cmd.ProgressBar("clip", width=10, stream=buf, unit="solves")(7, 7)
    assert buf.getvalue() == "clip [##########] 100% (7/7 solves)\n"


@pytest.mark.data
def test_feet_as_solved_leaves_the_legs_as_the_solve_put_them(
    shared_data_dir: Path, tmp_path: Path
) -> None:
    """By default a walk's swing feet are lifted and its feet held in double support;
    ``--feet-as-solved`` leaves them as solved: only leg joints differ between the two files,
    the ankles' pitch joints among them."""
    clip = shared_data_dir / "mocap" / "02" / "02_01.bvh"
    outs = {}
    for name, extra in (("lifted", ()), ("solved", ("--feet-as-solved",))):
        outs[name] = tmp_path / f"{name}.npz"
        assert _run(str(clip), "--robot", "op3", "--out", str(outs[name]), *extra) == 0
    lifted, solved = (RobotTrajectory.read(outs[k]) for k in ("lifted", "solved"))
    moved = {lifted.joint_names[j] for j in np.flatnonzero(np.abs(lifted.q - solved.q).max(0))}
    assert {"l_ank_pitch", "r_ank_pitch"} <= moved
    assert all(name.split("_")[1] in ("hip", "knee", "ank") for name in moved), moved


def test_the_summary_rates_the_solved_frames_and_counts_the_lead_in_apart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "t.npz"
    assert _run(str(FIXTURES / "tiny_walk.bvh"), "--out", str(out), "--lead-in") == 0
    traj = RobotTrajectory.read(out)
    lead = round(-traj.t0 * traj.fps)
    assert lead > 0
    summary = capsys.readouterr().out
    assert f"{traj.num_frames} frames ({lead} of them the lead-in's)" in summary
    line = next(s for s in summary.splitlines() if s.strip().startswith(str(out)))
    wall_s = float(line.split(", ")[1].split(" s ")[0])
    rate = float(line.split("(")[2].split(" frames/s")[0])
    solved = traj.num_frames - lead  # the rate is theirs, not the written frames' (the wall
    # time is printed to 10 ms, so nearer the one than the other)
    assert abs(rate - solved / wall_s) < abs(rate - traj.num_frames / wall_s), (rate, line)
