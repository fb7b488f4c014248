"""Counts and rates that must be positive are refused as the command line is read."""

from __future__ import annotations

import pytest

from robot_retarget.cli.main import main


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["eval", "--fps", "0"], "argument --fps: must be a positive number, got 0"),
        (["eval", "--max-frames", "0"], "argument --max-frames: must be at least 1, got 0"),
        (["eval", "--max-frames", "-1"], "argument --max-frames: must be at least 1, got -1"),
        (["crossval", "--fps", "nan"], "argument --fps: must be a positive number, got nan"),
        (["eval-robot", "--max-frames", "two"], "expected a whole number, got 'two'"),
        (["train", "--fps", "-30"], "argument --fps: must be a positive number, got -30"),
    ],
)
def test_zero_or_negative_counts_are_refused(
    argv: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    assert said in capsys.readouterr().err
