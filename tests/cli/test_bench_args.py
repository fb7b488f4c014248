"""Every bench target refuses a count or duration it cannot run with as a usage error, naming
the option, before any work (not a traceback, not a silently clamped run)."""

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
