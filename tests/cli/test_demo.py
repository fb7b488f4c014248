"""``demo``: the built-in clip end to end (short version: the first 4 s of the routine)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from PIL import Image

from robot_retarget.cli import demo_cmd
from robot_retarget.cli.output_paths import OutputPathError
from robot_retarget.errors import RetargetError
from robot_retarget.motion.trajectory import RobotTrajectory

TIME_LIMIT_S = 90


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    demo_cmd.configure(parser)
    return parser.parse_args(list(argv))


def test_short_demo_passes_its_checks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "demo"
    # 4 s: the ramped start (≥ 0.5 s at 25 % speed) catches the routine and hands over.
    assert demo_cmd.run(_args("--out-dir", str(out), "--seconds", "4")) == 0
    text = capsys.readouterr().out
    assert "FAIL" not in text, text
    assert text.count("[PASS]") == 6
    traj = RobotTrajectory.read(out / "demo_op3.npz")
    assert traj.num_frames == 501  # 4 s at 125 Hz
    assert RobotTrajectory.read(out / "demo_op3_stream.npz").num_frames > 100
    assert (out / "demo_op3.bvh").read_text().startswith("HIERARCHY")
    with Image.open(out / "demo_op3_preview.gif") as im:
        assert 5 <= im.n_frames <= 200
    with pytest.raises(RetargetError, match="--force"):
        demo_cmd.run(_args("--out-dir", str(out), "--seconds", "2"))


@pytest.mark.usefixtures("no_work")
@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (("--seconds", "20"), r"^--seconds must be in \[1, 12\] .*got 20$"),
        (("--seconds", "0"), r"^--seconds must be in \[1, 12\] .*got 0$"),
        (("--seconds", "0.01"), r"^--seconds must be in \[1, 12\] .*got 0.01$"),  # 1 frame
        (("--speed", "0"), r"^--speed must be positive, got 0$"),  # --seconds is fine
        (("--speed", "-2", "--seconds", "4"), r"^--speed must be positive, got -2$"),
        (("--speed", "inf"), r"^--speed must be positive, got inf$"),  # was "fps must be positive"
    ],
)
def test_bad_arguments_name_the_option_and_its_value(
    tmp_path: Path, argv: tuple[str, ...], said: str
) -> None:
    with pytest.raises(RetargetError, match=said):
        demo_cmd.run(_args("--out-dir", str(tmp_path), *argv))


@pytest.mark.usefixtures("no_work")
def test_unwritable_out_dir_is_refused_before_work(tmp_path: Path, read_only_dir: Path) -> None:
    with pytest.raises(OutputPathError, match=r"--out-dir .*not writable"):
        demo_cmd.run(_args("--out-dir", str(read_only_dir)))
    with pytest.raises(OutputPathError, match=r"--out-dir .*not writable"):
        demo_cmd.run(_args("--out-dir", str(read_only_dir / "new")))
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(OutputPathError, match="is a file, not a folder"):
        demo_cmd.run(_args("--out-dir", str(tmp_path / "a_file")))
    assert list(read_only_dir.iterdir()) == []


def test_a_clip_over_before_the_ramp_hands_over_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1 s of played clip (4 s at 4×): the stream never joins the trajectory, so the comparison
    cannot be made; the check says why and what to change instead of an infinite error."""
    args = _args("--out-dir", str(tmp_path / "d"), "--seconds", "4", "--speed", "4")
    args.no_preview = True
    assert demo_cmd.run(args) == 1
    text = capsys.readouterr().out
    assert "never compared, the played clip (1.0 s) ended before the start ramp" in text
    assert "error inf" not in text


def test_ctrl_c_while_streaming_stops_the_demo_and_says_what_was_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C in the stream: the loop stops smoothly (torque off) and the demo ends there with
    130, instead of failing its checks on the cut stream and rendering the preview anyway."""
    from robot_retarget.sources.base import SourceFrame
    from robot_retarget.sources.replay import ReplaySource

    polls = {"n": 0}
    poll = ReplaySource.poll

    def poll_then_ctrl_c(self: ReplaySource, now_s: float) -> list[SourceFrame]:
        polls["n"] += 1
        if polls["n"] == 100:
            raise KeyboardInterrupt
        return poll(self, now_s)

    monkeypatch.setattr(ReplaySource, "poll", poll_then_ctrl_c)
    out = tmp_path / "d"
    assert demo_cmd.run(_args("--out-dir", str(out), "--seconds", "4")) == 130
    captured = capsys.readouterr()
    assert "demo stopped by Ctrl-C while streaming: torque off" in captured.err
    assert "[FAIL]" not in captured.out
    assert "[PASS]" not in captured.out
    assert sorted(p.name for p in out.iterdir()) == ["demo_op3.bvh", "demo_op3.npz"]


@pytest.mark.usefixtures("no_work")
def test_outputs_are_named_after_the_config_not_the_robot_argument(tmp_path: Path) -> None:
    """--robot as a path: the files are demo_op3*, inside --out-dir (they were named after the
    path's text, in folders made from it, and with '..' in it outside --out-dir)."""
    repo = Path(__file__).resolve().parents[2]
    robot = repo / "configs" / "robots" / "op3" / ".." / "op3" / "op3.yaml"
    out = tmp_path / "out"
    out.mkdir()
    (out / "demo_op3.npz").write_text("an earlier demo")
    with pytest.raises(RetargetError, match=r"out/demo_op3\.npz.*--force"):
        demo_cmd.run(_args("--out-dir", str(out), "--robot", str(robot)))
    assert [p.name for p in tmp_path.rglob("*") if p.is_file()] == ["demo_op3.npz"]
