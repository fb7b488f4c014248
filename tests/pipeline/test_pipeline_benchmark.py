from __future__ import annotations

import argparse

import pytest

from robot_retarget.pipeline import benchmark


@pytest.mark.parametrize("positions", [False, True])
def test_records_per_stage(positions: bool) -> None:
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    args = parser.parse_args(["--frames", "30", "--warmup", "5"] + (["--positions"] * positions))
    records = benchmark.run(args)
    assert [r["stage"] for r in records] == list(benchmark.STAGES + benchmark.NUMPY_STAGES)
    for r in records:
        assert r["runs"] == 30
        assert 0 <= r["median_ms"] <= r["p99_ms"]
    by_stage = {r["stage"]: r for r in records}
    for total, parts in (
        ("total", benchmark.STAGES[:-1]),
        ("total, numpy path", benchmark.NUMPY_STAGES[:-1]),
    ):
        assert by_stage[total]["median_ms"] >= max(by_stage[p]["median_ms"] for p in parts) * 0.99
    assert benchmark.HELP


def test_bad_frame_count() -> None:
    with pytest.raises(ValueError, match="frames"):
        benchmark.run(argparse.Namespace(frames=0, warmup=0, robot="op3", model=None, source="3d",
                                         positions=False))  # fmt: skip


def test_records_per_stage_from_keypoints() -> None:
    from robot_retarget.pipeline.benchmark_2d import STAGES_2D

    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    records = benchmark.run(
        parser.parse_args(["--source", "2d", "--frames", "40", "--warmup", "5"])
    )
    assert [r["stage"] for r in records] == list(STAGES_2D)
    by_stage = {r["stage"]: r for r in records}
    assert by_stage["network"]["runs"] == 40
    # 125 Hz ticks, 30 fps camera: about one tick in four lifts a camera frame
    assert 5 <= by_stage["total, tick with a camera frame"]["runs"] <= 15
    for r in records:
        assert 0 <= r["median_ms"] <= r["p99_ms"]
