"""``crossval --model residual --steps N --out runs/cv``: subject-level cross-validation.

Trains the model once per CV fold (on the other CV folds; the held-out test fold excluded),
scores the final-step checkpoint and the copy baselines on the fold's clips with the ``eval``
code, prints mean ± spread over the folds, then trains on every CV subject and scores the
test fold (robot_retarget.evaluation.crossval; the folds: robot_retarget.evaluation.folds).
Trainings run one after another in this process; ``--resume`` continues a stopped run.
"""

from __future__ import annotations

import argparse
import json
import sys

from robot_retarget.cli.data_dir import add_data_argument
from robot_retarget.number_args import int_at_least, positive_float, positive_int, torch_device

NAME = "crossval"
HELP = "Subject-level cross-validation: train per fold, score unseen performers."


def configure(parser: argparse.ArgumentParser) -> None:
    from robot_retarget.nn.dataset import DEFAULT_FPS, DEFAULT_ROBOTS, DEFAULT_WINDOW_FRAMES
    from robot_retarget.nn.models.optimizers import LEARNING_RATE

    parser.add_argument(
        "--model",
        action="append",
        required=True,
        metavar="NAME",
        help="network to train per fold (nkn, pmnet, residual, san, tdcn); repeatable; copy and "
        "copy-scaled are always scored",
    )
    add_data_argument(parser)
    parser.add_argument("--out", required=True, help="output folder, e.g. runs/cv-residual")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out")
    parser.add_argument("--steps", type=positive_int, required=True, help="steps of every training")
    parser.add_argument(
        "--robot",
        action="append",
        default=None,
        help="robot whose canonical skeleton is a scoring target (repeatable; default op3)",
    )
    parser.add_argument(
        "--train-robots",
        default=",".join(DEFAULT_ROBOTS),
        help="robots whose skeletons are training targets (train --robots; default %(default)s)",
    )
    parser.add_argument(
        "--folds",
        default=None,
        metavar="FILE",
        help='JSON fold plan {"test": [...], "cv": [[...], ...]} (default: the plan for the '
        "shared ten subjects, robot_retarget.evaluation.folds)",
    )
    parser.add_argument("--batch-size", type=positive_int, default=32)
    parser.add_argument(
        "--window", type=int_at_least(2), default=DEFAULT_WINDOW_FRAMES, help="frames (≥ 2)"
    )
    parser.add_argument("--fps", type=positive_float, default=DEFAULT_FPS, help="common frame rate")
    parser.add_argument(
        "--lr", type=positive_float, default=LEARNING_RATE, help="Adam learning rate"
    )
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument(
        "--val-every", type=positive_int, default=500, help="steps between validations"
    )
    parser.add_argument("--checkpoint-every", type=positive_int, default=500)
    parser.add_argument(
        "--model-config",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="model constructor argument (as train --model-config; repeatable)",
    )
    parser.add_argument(
        "--max-frames", type=positive_int, default=None, help="first frames per clip"
    )
    parser.add_argument("--eval-seed", type=int, default=0, help="seed of the denoising noise")
    parser.add_argument("--threads", type=positive_int, default=None, help="torch CPU threads")
    parser.add_argument(
        "--device", type=torch_device, default="cpu", help="cpu, cuda, cuda:N or mps"
    )
    parser.add_argument("--cache-dir", default=None, help="preprocessed-data cache folder")
    output = parser.add_mutually_exclusive_group()
    output.add_argument("--json", action="store_true", help="print crossval.json's content")
    output.add_argument("--markdown", action="store_true", help="print Markdown tables")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def run(args: argparse.Namespace) -> int:
    import torch

    from robot_retarget.cli.train_cmd import _model_config
    from robot_retarget.evaluation.crossval import CrossvalConfig, crossval, format_report
    from robot_retarget.evaluation.folds import DEFAULT_FOLDS, load_folds
    from robot_retarget.nn.train import TrainProgress

    _check_arguments(args)
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    config = CrossvalConfig(
        models=tuple(args.model),
        data_dir=args.data,
        out_dir=args.out,
        steps=args.steps,
        robots=tuple(r for r in (args.robot or ["op3"]) if r != "none"),
        train_robots=tuple(r for r in args.train_robots.split(",") if r),
        batch_size=args.batch_size,
        window_frames=args.window,
        fps=args.fps,
        lr=args.lr,
        seed=args.seed,
        val_every=args.val_every,
        checkpoint_every=args.checkpoint_every,
        model_config=_model_config(args.model_config),
        max_frames=args.max_frames,
        eval_seed=args.eval_seed,
        threads=args.threads,
        folds=DEFAULT_FOLDS if args.folds is None else load_folds(args.folds),
        cache_dir=args.cache_dir,
        device=args.device,
    )

    def log(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr, flush=True)

    def progress(fold: str, p: TrainProgress) -> None:
        if args.quiet or (p.validation is None and p.step != p.total_steps):
            return
        val = "" if p.validation is None else f" val score {p.validation['score']:.4f}"
        loss = p.losses.get("total", float("nan"))
        print(
            f"{fold}: step {p.step}/{p.total_steps} loss {loss:.4f}{val} ({p.elapsed_s:.0f} s)",
            file=sys.stderr,
            flush=True,
        )

    report = crossval(config, resume=args.resume, log=log, progress=progress)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(format_report(report, markdown=args.markdown))
        print(
            f"\nper-fold numbers, train commands, git commit, data hash: {args.out}/crossval.json"
        )
    return 0


def _check_arguments(args: argparse.Namespace) -> None:
    """Before anything is written to --out (counts are checked as the command line is read):
    the robots named, a CUDA device torch sees, an --out that can be made and written, and a
    cross-validation there to --resume (a refused run must leave nothing to delete)."""
    from pathlib import Path

    from robot_retarget.cli.output_paths import check_folder
    from robot_retarget.cli.train_cmd import TrainArgumentError
    from robot_retarget.robot.loader import load_robot_config

    for robot in args.robot or []:
        if robot != "none":
            load_robot_config(robot)  # a ConfigError naming the robots there are
    from robot_retarget.nn.device import device_problem

    problem = device_problem(args.device)  # before the data load and the copy baselines' scores
    if problem is not None:
        raise TrainArgumentError(problem)
    out = Path(args.out)
    # A folder that can be made and written (crossval makes it as it writes crossval.json).
    check_folder(out, option="--out", create=True)
    if args.resume and not (out / "crossval.json").is_file():
        raise TrainArgumentError(
            f"--resume: nothing to resume, {out} holds no cross-validation (crossval.json); "
            "drop --resume to start one"
        )
