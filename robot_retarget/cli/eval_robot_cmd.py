"""``eval-robot --robot op3 --data DIR [--model NAME|PATH] [--json] [--plots DIR]``.

Converts every clip of the validation subjects with the full pipeline and scores it on the robot
against a position-IK baseline and the kinematic limit (robot_retarget.evaluation.robot).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from robot_retarget.cli.data_dir import add_data_argument
from robot_retarget.cli.foot_lock_arg import add_foot_lock_argument
from robot_retarget.number_args import non_negative_float, positive_float, positive_int
from robot_retarget.pipeline.input_filter import one_euro_argument

NAME = "eval-robot"
HELP = "Score the whole pipeline on the robot against a position-IK baseline and the limit."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or path (default op3)")
    add_data_argument(parser)
    parser.add_argument(
        "--model",
        default=None,
        metavar="NAME|PATH",
        help="model (default: the pipeline's); 'oracle': an ideal network (the human's own "
        "segment directions as the optimizer's targets)",
    )
    add_foot_lock_argument(parser)
    parser.add_argument(
        "--feet-as-solved",
        action="store_true",
        help="score the pipeline with its feet as solved: swing feet not lifted to the "
        "performer's height, feet not held in double support (as stream sends them; convert "
        "lifts and holds them)",
    )
    parser.add_argument(
        "--val-subjects",
        default=None,
        help="comma-separated subjects (default: the training split's validation subjects)",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of markdown")
    parser.add_argument("--plots", default=None, metavar="DIR", help="write PNG plots here")
    parser.add_argument(
        "--max-frames", type=positive_int, default=None, help="first frames per clip"
    )
    parser.add_argument(
        "--stride",
        type=positive_int,
        default=None,
        help="score every Nth control frame (default: 10 fps)",
    )
    parser.add_argument(
        "--eval-fps", type=positive_float, default=10.0, help="evaluation rate (default 10 fps)"
    )
    parser.add_argument(
        "--settle-s",
        type=non_negative_float,
        default=0.0,
        help="leave each clip's first seconds out of the direction and end-effector scores "
        "(the move from the init pose); default 0",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an optimizer option of the robot's 'retarget:' section (tuning runs)",
    )
    parser.add_argument(
        "--corrupt",
        default=None,
        metavar="KIND[,KIND…]|all",
        help="instead: play each clip as a live sender with this input corruption (jitter, "
        "dropout, swap, bone_length, latency, low_rate, or all) through the control loop, "
        "for the model and copy-scaled: direction error and its rise over clean input, the "
        "robot's deviation from its clean-input run, and jerk",
    )
    parser.add_argument(
        "--one-euro",
        type=one_euro_argument,
        default=None,
        metavar="MIN_HZ,BETA",
        help="with --corrupt: the loop smooths its input with this One-Euro filter, as "
        "stream --one-euro does",
    )
    parser.add_argument(
        "--oracle-smoothing",
        type=positive_float,
        default=None,
        metavar="MS",
        help="with --corrupt: a bound, not a live option: smooth every sender's stream (clean "
        "too) with a centred Gaussian of this σ in milliseconds before the live source, which "
        "removes jitter with no lag as no live filter can",
    )
    parser.add_argument(
        "--raw-positions",
        action="store_true",
        help="with --corrupt: the live source solves position packets as sent, as stream "
        "--raw-positions does (no frozen-joint, limb-swap or jitter cleanup)",
    )
    parser.add_argument(
        "--input",
        choices=("3d", "2d"),
        default="3d",
        help="2d: instead, each clip also seen by held-out virtual cameras as 2D keypoints with "
        "estimator-like noise, lifted by the keypoint model, scored beside the 3D input per view "
        "elevation (robot_retarget.evaluation.keypoints_2d)",
    )
    parser.add_argument(
        "--keypoint-model",
        default=None,
        help="--input 2d: the causal keypoint model of the stream rows, a runtime .npz "
        "(default: the shipped agnostic2d); also the clip rows' unless --clip-keypoint-model",
    )
    parser.add_argument(
        "--clip-keypoint-model",
        default=None,
        help="--input 2d: the keypoint model of the clip rows (convert), a runtime .npz, causal "
        "or centred (default: --keypoint-model if given, else the shipped agnostic2d_clip)",
    )
    parser.add_argument(
        "--no-image-planes",
        dest="image_planes",
        action="store_false",
        help="--input 2d: keep the keypoint model's answer as convert and stream "
        "--no-image-planes do (default: bones turned into the image's planes, as they do)",
    )
    parser.add_argument(
        "--cache-dir",
        default=None,
        help="kinematic-limit cache (default: the solver cache folder; 'none' to disable)",
    )


def _overrides(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise SystemExit(f"eval-robot: --set needs KEY=NUMBER, got {item!r}")
    return out


def run(args: argparse.Namespace) -> int:
    if args.plots is not None:
        if args.corrupt is not None or args.input == "2d":
            raise SystemExit(
                "eval-robot: --plots draws the clip rows' report; the --corrupt and --input 2d "
                "reports have no plots, leave it out"
            )
        from robot_retarget.cli.output_paths import check_folder

        # A folder that can be made and written, before any clip (the plots come last).
        check_folder(Path(args.plots), option="--plots", create=True)
    if args.one_euro is not None and args.corrupt is None:
        raise SystemExit("eval-robot: --one-euro smooths the live loop of --corrupt; add --corrupt")
    if (args.keypoint_model or args.clip_keypoint_model or not args.image_planes) and (
        args.input != "2d"
    ):
        raise SystemExit(
            "eval-robot: --keypoint-model, --clip-keypoint-model and --no-image-planes are "
            "about the 2D keypoint rows; add --input 2d"
        )
    if args.feet_as_solved and args.corrupt is not None:
        raise SystemExit(
            "eval-robot: --feet-as-solved is about the clip rows; the --corrupt runs play "
            "through the control loop, which sends the feet as solved already"
        )
    if args.oracle_smoothing is not None and args.corrupt is None:
        raise SystemExit(
            "eval-robot: --oracle-smoothing smooths the senders of --corrupt; add --corrupt"
        )
    if args.raw_positions and args.corrupt is None:
        raise SystemExit(
            "eval-robot: --raw-positions is about the live source of --corrupt; add --corrupt"
        )
    from robot_retarget.casadi_jit import default_cache_dir
    from robot_retarget.errors import RetargetError
    from robot_retarget.evaluation.robot.plots import segment_bars, stick_strip
    from robot_retarget.evaluation.robot.report import markdown_report, report_dict
    from robot_retarget.evaluation.robot.runner import (
        ORACLE_MODEL,
        EvalRobotSettings,
        evaluate_robot,
        oracle_runner,
        pipeline_runner,
        validation_clips,
        with_retarget_overrides,
    )
    from robot_retarget.evaluation.robot.segments import RobotBodyModel
    from robot_retarget.nn.dataset import DEFAULT_VALIDATION_SUBJECTS
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.robot.retarget_settings import RetargetSettings
    from robot_retarget.runtime.loader import check_foot_lock, load_runtime_model

    try:
        config = load_robot_config(args.robot)
        overrides = _overrides(args.set)
        # Checked here, so an error names --set, not the robot's file.
        RetargetSettings.from_mapping(
            overrides, bone_names=tuple(b.canonical for b in config.bones), path="--set"
        )
        config = with_retarget_overrides(config, overrides)
        subjects = DEFAULT_VALIDATION_SUBJECTS
        if args.val_subjects:
            subjects = tuple(s for s in args.val_subjects.split(",") if s)
        clips = validation_clips(args.data, subjects)
        model = args.model or default_model_name()
        if args.foot_lock:
            if model == ORACLE_MODEL:
                raise RetargetError("--foot-lock: the oracle has no network; leave it out")
            check_foot_lock(load_runtime_model(model), foot_lock=True)
        if args.corrupt is not None:
            return _corrupted(config, clips, str(model), args)
        if args.input == "2d":
            return _two_d(config, clips, str(model), args)
        cache = (
            default_cache_dir() / "eval_robot" if args.cache_dir is None else Path(args.cache_dir)
        )
        settings = EvalRobotSettings(
            eval_fps=args.eval_fps,
            stride=args.stride,
            max_frames=args.max_frames,
            settle_s=args.settle_s,
            cache_dir=None if args.cache_dir == "none" else cache,
        )

        def progress(name: str) -> None:
            print(f"  {name}", file=sys.stderr, flush=True)

        report = evaluate_robot(
            config,
            clips,
            oracle_runner(config)
            if model == ORACLE_MODEL
            else pipeline_runner(
                config,
                model,
                foot_lock=args.foot_lock,
                place_feet=not args.feet_as_solved,
            ),
            settings,
            model_name=_label(model, args),
            progress=progress,
        )
    except RetargetError as exc:
        print(f"eval-robot: {exc}", file=sys.stderr)
        return 1
    if args.plots:
        out = Path(args.plots)
        segment_bars(report, out / f"eval_robot_{report.robot}_segments.png")
        stick_strip(report, RobotBodyModel(config), out / f"eval_robot_{report.robot}_strip.png")
    if args.json:
        print(json.dumps(report_dict(report), indent=2))
    else:
        print(markdown_report(report))
    return 0


def _corrupted(config: Any, clips: Any, model: str, args: argparse.Namespace) -> int:
    """``--corrupt``: the model and copy-scaled under each corruption kind (live loop)."""
    from robot_retarget.errors import RetargetError
    from robot_retarget.evaluation.live_corruption import KINDS
    from robot_retarget.evaluation.robustness import markdown, robustness

    kinds = KINDS if args.corrupt == "all" else tuple(k for k in args.corrupt.split(",") if k)
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        raise RetargetError(f"--corrupt: unknown kind(s) {unknown}; choose from {', '.join(KINDS)}")
    models = [model] if model == "copy-scaled" else [model, "copy-scaled"]
    rows = robustness(config, clips, models, kinds, max_frames=args.max_frames or 600,
                      input_filter=args.one_euro, clean_positions=not args.raw_positions,
                      oracle_smoothing_s=None if args.oracle_smoothing is None
                      else args.oracle_smoothing / 1000.0,
                      foot_lock_models=[model] if args.foot_lock else [],
                      progress=lambda n: print(f"  {n}", file=sys.stderr, flush=True))  # fmt: skip
    rows = [dataclasses.replace(r, model=_label(r.model, args)) if r.model == model else r
            for r in rows]  # fmt: skip
    if args.json:
        print(json.dumps([r.__dict__ for r in rows], indent=2))
    else:
        print(markdown(rows))
        if args.oracle_smoothing is not None:
            print(f"Every sender's stream, clean too, smoothed with no lag (σ "
                  f"{args.oracle_smoothing:g} ms, --oracle-smoothing): a bound no live filter "
                  "reaches, not what stream runs.")  # fmt: skip
    return 0


def _two_d(config: Any, clips: Any, model: str, args: argparse.Namespace) -> int:
    """``--input 2d``: the clips from 3D and from 2D keypoints per held-out view."""
    from robot_retarget.errors import RetargetError
    from robot_retarget.evaluation.keypoints_2d import evaluate_2d, markdown_2d
    from robot_retarget.evaluation.robot.runner import pipeline_runner
    from robot_retarget.runtime.agnostic2d import load_keypoint_model

    stream_model = load_keypoint_model(args.keypoint_model)
    if stream_model.centered:
        raise RetargetError(
            f"--keypoint-model {args.keypoint_model}: it looks ahead (centered), so it cannot "
            "lift the stream rows; pass it as --clip-keypoint-model"
        )
    report = evaluate_2d(
        config,
        clips,
        _label(model, args),
        stream_model,
        # --keypoint-model alone lifts both row sets: the file is read once.
        clip_keypoint_model=stream_model
        if args.keypoint_model and not args.clip_keypoint_model
        else load_keypoint_model(args.clip_keypoint_model, whole_clip=True),
        pipeline=pipeline_runner(
            config, model, foot_lock=args.foot_lock, place_feet=not args.feet_as_solved
        ),
        stream_pipeline=pipeline_runner(
            config, model, foot_lock=args.foot_lock, whole_clip_branches=False
        ),
        max_frames=args.max_frames,
        image_planes=args.image_planes,
        progress=lambda n: print(f"  {n}", file=sys.stderr, flush=True),
    )
    if args.json:
        rows = {
            k: {
                "direction_error_deg": r.direction_deg,
                "limb_direction_error_deg": r.limb_deg,
                "seconds": r.seconds,
                "runs": r.runs,
                "limit_violations": r.limit_violations,
                "speed_violations": r.speed_violations,
            }
            for k, r in report.rows.items()
        }
        head = {"robot": report.robot, "model": report.model, "image_planes": report.image_planes}
        print(json.dumps({**head, "keypoint_model": report.keypoint_model, "rows": rows}, indent=2))
    else:
        print(markdown_2d(report))
    return 0


def _label(model: str, args: argparse.Namespace) -> str:
    """The model as the report names it: with its foot lock when ``--foot-lock`` ran it, and
    the ``--set`` overrides it ran with (so a saved report says how it differs)."""
    label = f"{model} + foot lock" if args.foot_lock else str(model)
    label = f"{label}, feet as solved" if args.feet_as_solved else label
    return f"{label} (--set {' '.join(args.set)})" if args.set else label
