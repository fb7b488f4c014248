"""eval-robot output: markdown table, goal check, JSON, plots."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from robot_retarget.evaluation.robot.plots import segment_bars, stick_strip
from robot_retarget.evaluation.robot.report import (
    goal_check,
    markdown_report,
    markdown_table,
    report_dict,
)
from robot_retarget.evaluation.robot.runner import (
    EvalRobotReport,
    EvalRobotSettings,
    RobotEvaluator,
    oracle_runner,
    summarize,
)
from robot_retarget.evaluation.robot.segments import RobotBodyModel
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.robot.config import RobotConfig


@pytest.fixture(scope="module")
def report(op3: RobotConfig) -> EvalRobotReport:
    motion = demo_motion(fps=125.0).frames(0, 125)
    settings = EvalRobotSettings(stride=25, random_starts=1)
    clip = RobotEvaluator(op3, oracle_runner(op3), settings).score_motion(motion, "demo")
    return EvalRobotReport("op3", "oracle", (clip,), summarize([clip]), 125.0, 25, 5, 1.0)


def test_table_has_every_metric_and_method(report: EvalRobotReport) -> None:
    table = markdown_table(report)
    lines = table.splitlines()
    assert lines[0] == (
        "| metric | pipeline | GMR-style IK | position-IK baseline | kinematic limit |"
    )
    assert len(lines) == 2 + 5 + 15
    assert all(line.count("|") == 6 for line in lines)
    assert "| joint-speed violations | 0 | 0 | 0 | — |" in lines
    assert any(line.startswith("| limb direction error, mean (°) |") for line in lines)


def test_goal_check_follows_the_numbers(report: EvalRobotReport) -> None:
    goals = {g: ok for g, ok, _ in goal_check(report)}
    assert goals["0 joint-limit violations"]
    assert goals["0 joint-speed violations"]
    s = dict(report.summary)
    s["limit"] = dataclasses.replace(
        s["limit"], segment_mean_deg={**s["limit"].segment_mean_deg,
                                      "overall": s["pipeline"].segment_mean_deg["overall"] - 1.9}
    )  # fmt: skip
    close = dataclasses.replace(report, summary=s)
    assert next(ok for g, ok, _ in goal_check(close) if "kinematic limit" in g)
    s["limit"] = dataclasses.replace(
        s["limit"], segment_mean_deg={**s["limit"].segment_mean_deg,
                                      "overall": s["pipeline"].segment_mean_deg["overall"] - 2.1}
    )  # fmt: skip
    far = dataclasses.replace(report, summary=s)
    assert not next(ok for g, ok, _ in goal_check(far) if "kinematic limit" in g)
    # Against GMR-style IK: the limbs' mean, at least 3° lower.
    limbs = s["pipeline"].segment_mean_deg["limbs"]
    for delta, met in ((3.1, True), (2.9, False)):
        s["gmr"] = dataclasses.replace(
            s["gmr"], segment_mean_deg={**s["gmr"].segment_mean_deg, "limbs": limbs + delta}
        )
        check = goal_check(dataclasses.replace(report, summary=s))
        assert next(ok for g, ok, _ in check if "GMR-style" in g) is met


def test_report_and_json(report: EvalRobotReport) -> None:
    text = markdown_report(report)
    assert "model oracle" in text
    assert "every 25th frame" in text
    assert "Goal (pipeline)" in text
    data = json.loads(json.dumps(report_dict(report)))
    assert set(data["summary"]) == {"pipeline", "gmr", "baseline", "limit"}
    assert "limbs" in data["summary"]["gmr"]["segment_mean_deg"]
    assert data["clips"][0]["clip"] == "demo"
    assert data["summary"]["limit"]["jerk_rad_s3"] is None


def test_plots_are_written(report: EvalRobotReport, op3: RobotConfig, tmp_path: Path) -> None:
    bars = segment_bars(report, tmp_path / "bars.png")
    strip = stick_strip(report, RobotBodyModel(op3), tmp_path / "sub" / "strip.png", count=3)
    for path in (bars, strip):
        assert path.is_file()
        assert path.read_bytes()[:4] == b"\x89PNG"
