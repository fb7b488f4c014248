"""``eval-robot --corrupt``: the robot's fidelity under live-input corruption, per kind.

Each clip is played as a live sender of each corruption kind
(:mod:`robot_retarget.evaluation.live_corruption`) through the real control loop
(:func:`robot_retarget.evaluation.live_replay.score_live`), once per model, and scored against
the clean performer; ``clean`` is the same sender uncorrupted. Reported per kind: mean segment
direction error (°), its rise over clean, the robot's deviation from its clean-input run (°,
:func:`robot_retarget.evaluation.live_replay.deviation_deg`) and mean jerk (rad/s³).

The deviation is the measure of how much a kind shakes or displaces the robot. The rise is not
one: a model that is closer to the performer on clean input rises more under the same noise
(errors add roughly in quadrature, and noise on a large, one-sided error can even shrink it).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_retarget.errors import InvalidMotionError
from robot_retarget.evaluation.live_corruption import KINDS, corrupt_stream
from robot_retarget.evaluation.live_replay import LiveScore, deviation_deg, score_live
from robot_retarget.evaluation.robot.segments import RobotBodyModel
from robot_retarget.evaluation.zero_lag_smoothing import zero_lag_smoothed
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.pipeline.input_filter import OneEuroSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig


@dataclass(frozen=True)
class RobustnessRow:
    model: str
    kind: str
    direction_deg: float
    jerk_rad_s3: float
    clips: int
    # Mean over clips of the robot's deviation from its own clean-input run (0 for clean).
    deviation_deg: float = 0.0


def robustness(
    config: RobotConfig,
    clips: Sequence[tuple[str, Path]],
    models: Sequence[str],
    kinds: Sequence[str] = KINDS,
    *,
    max_frames: int | None = 600,
    seed: int = 0,
    input_filter: OneEuroSettings | None = None,
    clean_positions: bool = True,
    oracle_smoothing_s: float | None = None,
    foot_lock_models: Collection[str] = (),
    progress: Callable[[str], None] | None = None,
) -> list[RobustnessRow]:
    """Mean over ``clips`` of each model under ``clean`` and each kind (same noise per clip);
    ``input_filter``: the loop smooths its input (``stream --one-euro``);
    ``clean_positions=False``: the source solves positions as sent (``--raw-positions``);
    ``oracle_smoothing_s``: every sender's stream (clean too) is first smoothed with no lag,
    a centred Gaussian of that σ (``--oracle-smoothing``: a bound, not a live filter);
    ``foot_lock_models``: the models that run their foot lock (``--foot-lock``)."""
    body = RobotBodyModel(config)
    rows = []
    for model in models:
        scores: dict[str, list[tuple[float, float, float]]] = {k: [] for k in ("clean", *kinds)}
        for k, (name, path) in enumerate(clips):
            if progress is not None:
                progress(f"{model}: {name}")
            motion = load_motion(path, max_frames=max_frames)
            step = RetargetStep(config, model, motion.skeleton, foot_lock=model in foot_lock_models)
            reference: LiveScore | None = None
            for kind in scores:  # clean first: the reference of the deviation
                rng = np.random.default_rng(seed + k)
                stream = corrupt_stream(motion, kind, rng)
                if oracle_smoothing_s is not None:
                    stream = zero_lag_smoothed(stream, oracle_smoothing_s)
                try:
                    s = score_live(
                        step,
                        motion,
                        stream,
                        body=body,
                        input_filter=input_filter,
                        clean_positions=clean_positions,
                    )
                except InvalidMotionError as exc:
                    raise InvalidMotionError(f"{name}: {exc}") from None
                if reference is None:  # this is the clean run
                    reference = s
                scores[kind].append((s.direction_deg, s.jerk_rad_s3, deviation_deg(s, reference)))
        for kind, vals in scores.items():
            a = np.array(vals)
            rows.append(RobustnessRow(model, kind, float(a[:, 0].mean()), float(a[:, 1].mean()),
                                      len(vals), float(a[:, 2].mean())))  # fmt: skip
    return rows


def markdown(rows: Sequence[RobustnessRow]) -> str:
    models = list(dict.fromkeys(r.model for r in rows))
    kinds = list(dict.fromkeys(r.kind for r in rows))
    by = {(r.model, r.kind): r for r in rows}
    head = "| input | " + " | ".join(f"{m}: direction (rise) / deviation / jerk" for m in models)
    head += " |"
    lines = [head, "|---|" + "---:|" * len(models)]
    for kind in kinds:
        cells = []
        for m in models:
            r, clean = by[(m, kind)], by[(m, "clean")]
            rise = r.direction_deg - clean.direction_deg
            direction = f"{r.direction_deg:.2f}° ({rise:+.2f})"
            cells.append(f"{direction} / {r.deviation_deg:.2f}° / {r.jerk_rad_s3:.0f}")
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
    n = rows[0].clips if rows else 0
    lines.append(f"\n{n} clips, each played live through the control loop; direction error "
                 "against the clean performer, deviation against the robot's own run on clean "
                 "input.")  # fmt: skip
    return "\n".join(lines)
