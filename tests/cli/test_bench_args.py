"""Every bench target, and eval, crossval, eval-robot, train and stream, refuse a count, rate or
duration it cannot run with as a usage error, naming the option, before any work (not a
traceback, not a silently clamped run)."""

from __future__ import annotations

import pytest

from robot_retarget.cli.main import main


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["bench", "pipeline", "--frames", "0"], "--frames"),
        (["bench", "pipeline", "--warmup", "-1"], "--warmup"),
        (["bench", "model", "--threads", "0"], "--threads"),
        (["bench", "model", "--clip-repeats", "0"], "--clip-repeats"),
        (["bench", "convert", "--clips", "0"], "--clips"),
        (["bench", "convert", "--repeat", "0"], "--repeat"),
        (["bench", "loop", "--frames", "0"], "--frames"),
        (["bench", "loop", "--rounds", "0"], "--rounds"),
        (["bench", "stream", "--seconds", "-1"], "--seconds"),
        (["bench", "stream", "--rate", "inf"], "--rate"),
        (["bench", "solve", "--frames", "0"], "--frames"),
        (["eval", "--fps", "0"], "--fps"),  # was a ZeroDivisionError traceback
        (["eval", "--max-frames", "0"], "--max-frames"),  # was a ValueError traceback
        (["eval", "--max-frames", "-1"], "--max-frames"),  # was taken
        (["crossval", "--fps", "nan"], "--fps"),
        (["eval-robot", "--max-frames", "two"], "--max-frames"),
        (["eval-robot", "--eval-fps", "0"], "--eval-fps"),  # was a ZeroDivisionError traceback
        (["eval-robot", "--eval-fps", "-5"], "--eval-fps"),  # was taken
        (["eval-robot", "--stride", "0"], "--stride"),  # was taken
        (["eval-robot", "--stride", "-1"], "--stride"),  # was a traceback
        (["eval-robot", "--settle-s", "-1"], "--settle-s"),  # was a traceback
        (["train", "--fps", "-30"], "--fps"),
        (["stream", "--source", "udp://127.0.0.1:9", "--stats-every", "0"], "--stats-every"),
        (["stream", "--source", "udp://127.0.0.1:9", "--rate", "inf"], "--rate"),  # was taken
        (["stream", "--source", "udp://127.0.0.1:9", "--duration", "-1"], "--duration"),
        (["stream", "--source", "udp://127.0.0.1:9", "--rate", "-5"], "--rate"),
    ],
)
def test_bad_counts_are_usage_errors(
    argv: list[str], option: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}:" in err
    assert "Traceback" not in err


def test_the_refusal_says_what_was_expected(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["eval", "--max-frames", "0"])
    assert "argument --max-frames: must be at least 1, got 0" in capsys.readouterr().err
