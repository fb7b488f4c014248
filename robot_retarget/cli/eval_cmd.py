"""``eval --model NAME|PATH --data DIR [--robot op3] [--json]``: score models on unseen subjects.

Loads the clips of the validation subjects (the training default, or ``--val-subjects``; every
clip with ``--val-subjects all`` or when the folder holds none of the default ones), retargets
each onto the other validation subjects' skeletons and the robot's
canonical skeleton, and prints one table row per model (robot_retarget.evaluation.runner).
``--model`` is repeatable: ``--model copy --model copy-scaled --model runs/x/best.pt``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from robot_retarget.cli.data_dir import add_data_argument
from robot_retarget.number_args import positive_float, positive_int

if TYPE_CHECKING:  # torch is imported by the command, not by the CLI's import
    from robot_retarget.array_types import FloatArray
    from robot_retarget.evaluation.runner import EvalResult, EvalSettings
    from robot_retarget.nn.dataset import Clip
    from robot_retarget.nn.inference import LoadedModel

NAME = "eval"
HELP = "Evaluate retargeting models on validation subjects (errors, skate, denoising)."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--model",
        action="append",
        default=None,
        metavar="NAME|PATH",
        help="model name (copy, copy-scaled, a shipped checkpoint) or checkpoint path / run "
        "folder; repeatable (default: copy, copy-scaled and the shipped default model)",
    )
    add_data_argument(parser)
    parser.add_argument(
        "--robot",
        action="append",
        default=None,
        help="robot config whose canonical skeleton is a target (repeatable; default op3; "
        "'none' for no robot)",
    )
    parser.add_argument(
        "--val-subjects",
        default=None,
        help="comma-separated subjects to evaluate on, or 'all' for every clip of --data "
        "(default: the training split's validation subjects; a folder holding none of them, "
        "other performers or your own recordings, is scored whole)",
    )
    parser.add_argument("--fps", type=positive_float, default=None, help="frame rate (default 30)")
    parser.add_argument(
        "--max-frames", type=positive_int, default=None, help="first frames per clip"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the denoising noise")
    output = parser.add_mutually_exclusive_group()
    output.add_argument("--json", action="store_true", help="print JSON instead of a table")
    output.add_argument("--markdown", action="store_true", help="print a Markdown table")
    parser.add_argument("--cache-dir", default=None, help="preprocessed-data cache folder")
    parser.add_argument(
        "--without-foot-lock",
        action="store_true",
        help="also score each model that has a foot lock without it, as convert and stream run "
        "it on the robot by default, one more row each",
    )
    parser.add_argument(
        "--native-input",
        action="store_true",
        help="also score skeleton-aware models (san) reading each clip on its file's own "
        "skeleton, one more row each",
    )


def run(args: argparse.Namespace) -> int:
    from robot_retarget.evaluation.runner import (
        EvalSettings,
        acceptance,
        evaluate,
        format_table,
    )
    from robot_retarget.nn.dataset import (
        DEFAULT_FPS,
        DEFAULT_VALIDATION_SUBJECTS,
        load_dataset,
        robot_skeletons,
    )
    from robot_retarget.nn.inference import DEFAULT_MODEL, load_model, shipped_checkpoints
    from robot_retarget.nn.models.san import SAN

    _check_arguments(args)
    names = args.model or ["copy", "copy-scaled"] + (
        [DEFAULT_MODEL] if DEFAULT_MODEL in shipped_checkpoints() else []
    )
    models = [load_model(n) for n in names]
    subjects: tuple[str, ...] = DEFAULT_VALIDATION_SUBJECTS
    if args.val_subjects is not None:
        subjects = tuple(s for s in args.val_subjects.split(",") if s)
    fps = DEFAULT_FPS if args.fps is None else args.fps
    dataset = load_dataset(args.data, fps=fps, cache_dir=args.cache_dir)
    whole = subjects == ("all",) or (
        not args.val_subjects and not set(subjects) & set(dataset.subjects)
    )
    if whole:  # no training split to respect: every clip is scored
        print(
            f"scoring all {len(dataset.clips)} clips of {len(dataset.subjects)} subject(s) "
            f"under {args.data}",
            file=sys.stderr,
        )
        val = dataset
    else:
        if args.val_subjects is None:  # the default validation subjects the folder holds
            subjects = tuple(x for x in subjects if x in dataset.subjects)
        # Scored only: a folder of validation subjects alone needs no training subject.
        val = dataset.only(subjects)
    robot_names = [r for r in (args.robot or ["op3"]) if r != "none"]
    robots = robot_skeletons(tuple(robot_names))
    settings = EvalSettings(robots=tuple(robot_names), max_frames=args.max_frames, seed=args.seed)
    if args.without_foot_lock and not any(_has_foot_lock(m) for m in models):
        print(
            "note: --without-foot-lock scores models that have a foot lock a second time; none "
            f"of {names} has one, so no row is added",
            file=sys.stderr,
        )
    if args.native_input and not any(isinstance(m.model, SAN) for m in models):
        print(
            "note: --native-input scores skeleton-aware models (san) a second time; none of "
            f"{names} is one, so no row is added",
            file=sys.stderr,
        )
    results = []
    for m in models:
        trained_on = set(m.metadata.get("train_subjects", []))
        leaked = sorted(trained_on & set(val.subjects))
        if leaked:
            print(
                f"warning: {m.name} was trained on evaluation subject(s) {leaked}",
                file=sys.stderr,
            )
        results.append(evaluate(m, val.clips, robots, settings))
        if args.without_foot_lock and _has_foot_lock(m):
            results.append(_without_foot_lock(m, val.clips, robots, settings))
        if args.native_input and isinstance(m.model, SAN):
            native = dataclasses.replace(settings, native_input=True)
            results.append(evaluate(m, val.clips, robots, native))
    if args.json:
        print(
            json.dumps(
                {
                    "subjects": list(val.subjects),
                    "robots": robot_names,
                    "fps": fps,
                    "results": [r.to_json() for r in results],
                },
                indent=2,
            )
        )
    else:
        print(format_table(results, markdown=args.markdown))
        print(
            f"\n{results[0].clips if results else 0} clips of subjects {', '.join(val.subjects)}; "
            f"targets: other subjects + {', '.join(robot_names) or 'no robot'}; lower is better",
        )
        names = [r.model for r in results]
        if "copy" in names and "copy-scaled" in names:
            for r in results:
                if r.model in ("copy", "copy-scaled"):
                    continue
                print(f"\nacceptance goals of {r.model}:")
                for check in acceptance(results, r.model):
                    mark = "met" if check.met else "NOT met"
                    print(f"  {check.goal}: {mark} ({check.detail})")
    return 0


def _check_arguments(args: argparse.Namespace) -> None:
    """Before any model or clip loads: a --val-subjects that names no subject, a model named
    twice, and 'none' beside a robot (each was taken: an empty table with exit code 0, the
    default subjects, a row printed twice, the robot alone)."""
    if args.val_subjects is not None and not [s for s in args.val_subjects.split(",") if s]:
        raise SystemExit(
            f"eval: --val-subjects {args.val_subjects!r} names no subject; give subjects such as "
            "06,08,12, or 'all' for every clip of --data (leave it out for the default split)"
        )
    twice = sorted({m for m in args.model or [] if args.model.count(m) > 1})
    if twice:
        raise SystemExit(f"eval: --model {', '.join(twice)} given twice; name each model once")
    robots = args.robot or []
    if "none" in robots and len(robots) > 1:
        others = ", ".join(r for r in robots if r != "none")
        raise SystemExit(
            f"eval: --robot none (no robot target) contradicts --robot {others}; pass one of them"
        )


def _has_foot_lock(m: LoadedModel) -> bool:
    from robot_retarget.nn.models.residual import ResidualRetargeter

    return isinstance(m.model, ResidualRetargeter) and m.model.lock is not None


def _without_foot_lock(
    m: LoadedModel, clips: Sequence[Clip], robots: Mapping[str, FloatArray], settings: EvalSettings
) -> EvalResult:
    """``m`` scored with its foot lock taken out for the run (the robot path's default)."""
    from robot_retarget.evaluation.runner import evaluate
    from robot_retarget.nn.models.residual import ResidualRetargeter

    net = m.model
    assert isinstance(net, ResidualRetargeter)  # _has_foot_lock said so
    lock = net.lock
    net.lock = None
    try:
        return evaluate(dataclasses.replace(m, name=f"{m.name}, no foot lock"), clips, robots,
                        settings)  # fmt: skip
    finally:
        net.lock = lock
