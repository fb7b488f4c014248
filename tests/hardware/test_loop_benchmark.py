"""bench loop: byte counts behind the wire limits, and a short real run on the simulated bus."""

from __future__ import annotations

import argparse

import pytest

from robot_retarget.hardware import benchmark
from robot_retarget.robot.config import RobotConfig


def test_wire_limits_match_the_design_numbers() -> None:
    # DESIGN.md: 20 servos, 4-byte values, 2 Mbps: ≥ 2.24 ms, 1.58 ms with fast sync read.
    assert benchmark.cycle_bytes(2.0, 20, 4, fast=False) == 114 + 334
    assert benchmark.cycle_bytes(2.0, 20, 4, fast=False) * 10 / 2e6 * 1e3 == pytest.approx(2.24)
    assert benchmark.cycle_bytes(2.0, 20, 4, fast=True) * 10 / 2e6 * 1e3 == pytest.approx(1.58)
    # Protocol 1.0, 2 servos with 2-byte values, one read by Bulk Read, one alone:
    # sync write 8 + 2·3, bulk read 7 + 3 + (6 + 2), single read 8 + (6 + 2).
    assert benchmark.cycle_bytes(1.0, 2, 2, fast=False, n_single=1) == 14 + 18 + 16


def test_read_size_counts_the_state_block() -> None:
    # The backend's per-tick block on OP3: 4-byte goals out, 10 bytes per servo back.
    fast = benchmark.cycle_bytes(2.0, 20, 4, fast=True, read_size=10)
    assert fast == 114 + 34 + 8 + 20 * 14


def test_bench_loop_runs(op3: RobotConfig) -> None:
    if op3.source_path is None:
        pytest.skip("configs/robots/op3.yaml not available to the loader yet")
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    records = benchmark.run(
        parser.parse_args(["--robot", "op3", "--frames", "40", "--warmup", "5", "--rounds", "4"])
    )
    modes = [r["mode"] for r in records]
    stages = [f"stage:{s}" for s in benchmark.STAGES]
    assert modes == [
        "sdk_sync_write+sync_read",
        "sdk_sync_write+fast_sync_read",
        "backend_send+read_state",
        *stages,
        "sdk_sync_write+sync_read+wire",
        "sdk_sync_write+fast_sync_read+wire",
        "backend_send+read_state+wire",
        *(f"{s}+wire" for s in stages),
    ]
    for r in records:
        assert {"mode", "median_ms", "p99_ms", "hz"} <= set(r)
        assert 0 < r["median_ms"] <= r["p99_ms"] + 1e-9
        assert r["runs"] == 40
    backend = records[2]
    assert backend["ratio_median"] == pytest.approx(backend["median_ms"] / records[1]["median_ms"])
    assert all(r["runs"] == 40 for r in records[3 : 3 + len(stages)])  # one sample per tick
    # With the wire model a cycle cannot beat the wire.
    wire = records[3 + len(stages) :]
    for r in wire[:3]:
        assert r["median_ms"] >= 0.95 * r["wire_limit_ms"]


def test_bench_loop_poppy_reads_by_bulk_read(poppy: RobotConfig) -> None:
    if poppy.source_path is None:
        pytest.skip("configs/robots/poppy_humanoid.yaml not available to the loader yet")
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    args = ["--robot", "poppy_humanoid", "--frames", "20", "--warmup", "2", "--no-wire"]
    records = benchmark.run(parser.parse_args(args))
    assert [r["mode"] for r in records[:2]] == [
        "sdk_sync_write+bulk_read",
        "backend_send+read_state",
    ]
    assert records[1]["servos"] == poppy.num_joints
