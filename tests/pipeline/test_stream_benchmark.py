"""bench stream: a plain and a watched run on the simulated bus, each reporting its ticks."""

from __future__ import annotations

import argparse

import pytest

from robot_retarget.pipeline import stream_benchmark

TIME_LIMIT_S = 120


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    stream_benchmark.configure(parser)
    return parser.parse_args(list(argv))


def test_plain_and_watched_runs_are_reported() -> None:
    pytest.importorskip("viser", reason="--view needs the [view] extra (pip install viser)")
    records = stream_benchmark.run(_args("--seconds", "1.0", "--repeats", "1", "--view"))
    assert [r["variant"] for r in records] == ["plain", "view (ws)"]
    for r in records:
        # 125 Hz for 1 s: every scheduled tick either ran or was counted as overrun.
        assert r["ticks"] + r["overruns"] >= 120
        assert r["ticks"] > 0
        assert r["jitter_median_ms"] >= 0.0
    watched = records[1]
    assert watched["published"] > 0  # the page drew frames while a client read them
    assert watched["publish_median_ms"] > 0.0


def test_bad_settings_are_refused() -> None:
    """On the command line, before any work (a usage error); and from code, by ``run``."""
    from robot_retarget.errors import RetargetError

    with pytest.raises(SystemExit):
        _args("--repeats", "0")
    args = _args()
    args.repeats = 0
    with pytest.raises(RetargetError, match="--repeats"):
        stream_benchmark.run(args)
