"""eval-robot output: the markdown table, the goal check and a JSON form."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from robot_retarget.evaluation.robot.runner import METHODS, EvalRobotReport, MethodSummary
from robot_retarget.evaluation.robot.segments import KINDS

# The goal for the pipeline (OP3, unseen subjects).
GOAL_MARGIN_DEG = 1.5


def _fmt(value: float | int | None, digits: int = 2) -> str:
    if value is None:
        return "—"
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}f}"


def markdown_table(report: EvalRobotReport) -> str:
    """Rows: metrics; columns: pipeline, baseline (position IK), kinematic limit."""
    s = report.summary
    rows: list[tuple[str, list[str]]] = []
    for kind in KINDS:
        rows.append(
            (f"{kind.replace('_', ' ')} direction error (°)",
             [_fmt(s[m].segment_mean_deg[kind]) for m in METHODS])
        )  # fmt: skip
    rows += [
        (
            "**direction error, mean (°)**",
            [_fmt(s[m].segment_mean_deg["overall"]) for m in METHODS],
        ),
        ("direction error, p95 (°)", [_fmt(s[m].segment_p95_deg) for m in METHODS]),
        ("hand error (arm lengths)", [_fmt(s[m].ee_hands, 3) for m in METHODS]),
        ("foot error (leg lengths)", [_fmt(s[m].ee_feet, 3) for m in METHODS]),
        ("**end-effector error**", [_fmt(s[m].ee_overall, 3) for m in METHODS]),
        ("joint-limit violations", [_fmt(s[m].limit_violations) for m in METHODS]),
        ("joint-speed violations", [_fmt(s[m].speed_violations) for m in METHODS]),
        ("max joint speed (rad/s)", [_fmt(s[m].max_speed_rad_s) for m in METHODS]),
        ("**jerk (rad/s³)**", [_fmt(s[m].jerk_rad_s3, 0) for m in METHODS]),
        ("solver fallbacks", [_fmt(s[m].fallbacks) for m in METHODS]),
        ("compute per frame (ms)", [_fmt(s[m].ms_per_frame, 3) for m in METHODS]),
    ]
    head = "| metric | pipeline | position-IK baseline | kinematic limit |"
    lines = [head, "|---|---:|---:|---:|"]
    lines += [f"| {name} | {' | '.join(vals)} |" for name, vals in rows]
    return "\n".join(lines)


def goal_check(report: EvalRobotReport) -> list[tuple[str, bool, str]]:
    """(goal, met, numbers) for each part of the issue's goal."""
    p, b, lim = (report.summary[m] for m in METHODS)
    gap = p.segment_mean_deg["overall"] - lim.segment_mean_deg["overall"]
    return [
        ("0 joint-limit violations", p.limit_violations == 0, f"{p.limit_violations}"),
        ("0 joint-speed violations", p.speed_violations == 0, f"{p.speed_violations}"),
        (
            f"direction error within {GOAL_MARGIN_DEG}° of the kinematic limit",
            gap <= GOAL_MARGIN_DEG,
            f"{p.segment_mean_deg['overall']:.2f}° vs {lim.segment_mean_deg['overall']:.2f}° "
            f"(gap {gap:+.2f}°)",
        ),
        (
            "end-effector error ≤ baseline",
            p.ee_overall <= b.ee_overall,
            f"{p.ee_overall:.3f} vs {b.ee_overall:.3f}",
        ),
        (
            "jerk ≤ baseline",
            (p.jerk_rad_s3 or 0.0) <= (b.jerk_rad_s3 or 0.0),
            f"{_fmt(p.jerk_rad_s3, 0)} vs {_fmt(b.jerk_rad_s3, 0)} rad/s³",
        ),
    ]


def markdown_report(report: EvalRobotReport) -> str:
    """Header line, table and goal check."""
    head = (
        f"eval-robot — robot {report.robot}, model {report.model}, {len(report.clips)} clips, "
        f"{report.eval_frames} evaluation frames (every {report.stride}th frame at "
        f"{report.rate_hz:g} Hz"
        + (f", scored after the first {report.settle_s:g} s" if report.settle_s > 0 else "")
        + f"), {report.wall_s:.0f} s"
    )
    goals = "\n".join(
        f"- [{'x' if ok else ' '}] {goal}: {numbers}" for goal, ok, numbers in goal_check(report)
    )
    return f"{head}\n\n{markdown_table(report)}\n\nGoal (pipeline):\n{goals}\n"


def _summary_dict(s: MethodSummary) -> dict[str, Any]:
    return {
        "segment_mean_deg": dict(s.segment_mean_deg),
        "segment_p95_deg": s.segment_p95_deg,
        "ee_hands": s.ee_hands,
        "ee_feet": s.ee_feet,
        "ee_overall": s.ee_overall,
        "limit_violations": s.limit_violations,
        "speed_violations": s.speed_violations,
        "max_speed_rad_s": s.max_speed_rad_s,
        "jerk_rad_s3": s.jerk_rad_s3,
        "fallbacks": s.fallbacks,
        "ms_per_frame": s.ms_per_frame,
    }


def report_dict(report: EvalRobotReport) -> dict[str, Any]:
    """JSON-ready summary: settings, per-method aggregates, goal check, per-clip means."""
    clips: list[Mapping[str, Any]] = [
        {
            "clip": c.name,
            "duration_s": c.duration_s,
            **{
                m: {
                    "segment_mean_deg": float(
                        c.methods[m].angles.mean() * 180.0 / 3.141592653589793
                    ),
                    "ee_mean": float(c.methods[m].ee.mean()),
                }
                for m in METHODS
            },
        }
        for c in report.clips
    ]
    return {
        "robot": report.robot,
        "model": report.model,
        "rate_hz": report.rate_hz,
        "stride": report.stride,
        "eval_frames": report.eval_frames,
        "wall_s": report.wall_s,
        "settle_s": report.settle_s,
        "summary": {m: _summary_dict(report.summary[m]) for m in METHODS},
        "goal": [{"goal": g, "met": ok, "numbers": n} for g, ok, n in goal_check(report)],
        "clips": clips,
    }
