"""eval-robot output: the markdown table, the goal check and a JSON form."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from robot_retarget.evaluation.robot.runner import (
    METHOD_LABELS,
    METHODS,
    EvalRobotReport,
    MethodSummary,
)
from robot_retarget.evaluation.robot.segments import KINDS

# The acceptance target of issue #11 for the pipeline.
GOAL_MARGIN_DEG = 2.0  # direction error at most this much above the kinematic limit
GOAL_BELOW_GMR_DEG = 3.0  # … and at least this much below the GMR-style baseline


def _fmt(value: float | int | None, digits: int = 2) -> str:
    if value is None:
        return "—"
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}f}"


def markdown_table(report: EvalRobotReport) -> str:
    """Rows: metrics; columns: pipeline, GMR-style IK, position-IK baseline, kinematic limit."""
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
        (
            "limb direction error, mean (°)",
            [_fmt(s[m].segment_mean_deg["limbs"]) for m in METHODS],
        ),
        ("direction error, p95 (°)", [_fmt(s[m].segment_p95_deg) for m in METHODS]),
        ("hand error (arm lengths)", [_fmt(s[m].ee_hands, 3) for m in METHODS]),
        ("foot error (leg lengths)", [_fmt(s[m].ee_feet, 3) for m in METHODS]),
        ("**end-effector error**", [_fmt(s[m].ee_overall, 3) for m in METHODS]),
        ("joint-limit violations", [_fmt(s[m].limit_violations) for m in METHODS]),
        ("joint-speed violations", [_fmt(s[m].speed_violations) for m in METHODS]),
        ("max joint speed (rad/s)", [_fmt(s[m].max_speed_rad_s) for m in METHODS]),
        ("**jerk (rad/s³)**", [_fmt(s[m].jerk_rad_s3, 0) for m in METHODS]),
        ("robot foot skate (m/s)", [_fmt(s[m].foot_skate_m_s, 3) for m in METHODS]),
        (
            "… under the performer's planted feet (m/s)",
            [_fmt(s[m].planted_skate_m_s, 3) for m in METHODS],
        ),
        (
            "swing foot within 1 cm of the floor (share of swing frames)",
            [_fmt(s[m].swing_scuff_share, 3) for m in METHODS],
        ),
        ("solver fallbacks", [_fmt(s[m].fallbacks) for m in METHODS]),
        ("compute per frame (ms)", [_fmt(s[m].ms_per_frame, 3) for m in METHODS]),
    ]
    head = "| metric | " + " | ".join(METHOD_LABELS[m] for m in METHODS) + " |"
    lines = [head, "|---|" + "---:|" * len(METHODS)]
    lines += [f"| {name} | {' | '.join(vals)} |" for name, vals in rows]
    return "\n".join(lines)


def goal_check(report: EvalRobotReport) -> list[tuple[str, bool, str]]:
    """(goal, met, numbers) for each part of the acceptance target (issue #11)."""
    p, g, b, lim = (report.summary[m] for m in METHODS)
    d_p, d_l = (s.segment_mean_deg["overall"] for s in (p, lim))
    # GMR-style IK has no torso task (its torso is whatever its spine joints end at, on a base
    # that follows the performer's trunk): compared on the limbs.
    l_p, l_g = (s.segment_mean_deg["limbs"] for s in (p, g))
    return [
        ("0 joint-limit violations", p.limit_violations == 0, f"{p.limit_violations}"),
        ("0 joint-speed violations", p.speed_violations == 0, f"{p.speed_violations}"),
        (
            f"limb direction error ≥ {GOAL_BELOW_GMR_DEG:g}° below the GMR-style baseline",
            l_p <= l_g - GOAL_BELOW_GMR_DEG,
            f"{l_p:.2f}° vs {l_g:.2f}° ({l_p - l_g:+.2f}°)",
        ),
        (
            f"direction error within {GOAL_MARGIN_DEG:g}° of the kinematic limit",
            d_p - d_l <= GOAL_MARGIN_DEG,
            f"{d_p:.2f}° vs {d_l:.2f}° (gap {d_p - d_l:+.2f}°)",
        ),
        (
            "end-effector error ≤ both baselines",
            p.ee_overall <= min(g.ee_overall, b.ee_overall),
            f"{p.ee_overall:.3f} vs GMR-style {g.ee_overall:.3f}, position IK {b.ee_overall:.3f}",
        ),
        (
            "jerk ≤ the position-IK baseline",
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
    note = (
        "Every method stands on a floating base, scored in the world: the pipeline on its "
        "trajectory's own (the network's trunk frames), the others on the performer's trunk "
        "frames. GMR-style IK has no torso task: compare it on the limb rows."
    )
    return f"{head}\n\n{markdown_table(report)}\n\n{note}\n\nGoal (pipeline):\n{goals}\n"


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
        "foot_skate_m_s": s.foot_skate_m_s,
        "planted_skate_m_s": s.planted_skate_m_s,
        "swing_scuff_share": s.swing_scuff_share,
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
                    "foot_skate_m_s": c.methods[m].foot_skate_m_s,
                    "planted_skate_m_s": c.methods[m].planted_skate_m_s,
                    "swing_scuff_share": c.methods[m].swing_scuff_share,
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
