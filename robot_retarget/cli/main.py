"""Top-level argument parsing: one sub-command per module listed in COMMAND_MODULES.

Command modules are imported lazily, only the one being run, so ``--help`` and light commands
never pay for importing torch or casadi.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import cast

from robot_retarget import __version__
from robot_retarget.cli.command import Command
from robot_retarget.cli.missing_torch import MissingTorchError, is_missing_torch
from robot_retarget.errors import RetargetError

# (command name, module, one-line help). The help lives here too so --help needs no imports.
COMMANDS: tuple[tuple[str, str, str], ...] = (
    ("demo", "robot_retarget.cli.demo_cmd", "Built-in demo: clip -> OP3 on a simulated bus."),
    ("convert", "robot_retarget.cli.convert_cmd", "Retarget BVH clip(s) to a robot trajectory."),
    ("stream", "robot_retarget.cli.stream_cmd", "Drive a robot live from a clip or mocap stream."),
    ("inspect", "robot_retarget.cli.inspect_cmd", "Describe motion, trajectory and robot files."),
    ("doctor", "robot_retarget.cli.doctor_cmd", "Check a Dynamixel bus: ports, servos, latency."),
    ("train", "robot_retarget.cli.train_cmd", "Train a retargeting network on BVH clips."),
    ("eval", "robot_retarget.cli.eval_cmd", "Evaluate retargeting models on unseen subjects."),
    ("crossval", "robot_retarget.cli.crossval_cmd", "Cross-validate a model over subject folds."),
    ("eval-robot", "robot_retarget.cli.eval_robot_cmd", "Score the pipeline on a robot."),
    ("bench", "robot_retarget.cli.bench_cmd", "Speed benchmarks: median and p99 of each stage."),
    ("export", "robot_retarget.cli.export_cmd", "Export a checkpoint to its numpy runtime."),
    ("view", "robot_retarget.cli.view_cmd", "Show a trajectory and its clip in a browser."),
)


def _load(module: str) -> Command:
    return cast(Command, importlib.import_module(module))


def build_parser(selected: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="robot-retarget",
        description="Retarget human motion to Dynamixel-servo humanoids.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module, help_text in COMMANDS:
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == selected:
            _load(module).configure(p)
        else:
            # Parsed only to produce the top-level help; real arguments load with the command.
            p.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    return parser


# OpenBLAS threads for numpy, unless the user set their own. The per-frame arithmetic multiplies
# matrices of a few dozen rows: a second BLAS thread costs more to wake than it saves (the
# residual network's denoiser: 41 µs with OpenBLAS's threads, 21 µs with one) and, on a busy
# machine, it competes with the control loop. Torch keeps its own threads (train --threads).
BLAS_THREADS_ENV = "OPENBLAS_NUM_THREADS"


def _torch_missing(command: str | None, exc: ImportError) -> int:
    """Exit 1 with the one-line answer if ``exc`` is torch missing; re-raise anything else."""
    if not is_missing_torch(exc):
        raise exc
    print(f"error: {MissingTorchError(f'robot-retarget {command}', str(exc))}", file=sys.stderr)
    return 1


def main(argv: Sequence[str] | None = None) -> int:
    # Before any command module imports numpy (OpenBLAS reads it once, when it loads).
    os.environ.setdefault(BLAS_THREADS_ENV, "1")
    args_list = list(sys.argv[1:] if argv is None else argv)
    names = {name for name, _, _ in COMMANDS}
    selected = next((a for a in args_list if not a.startswith("-")), None)
    if selected not in names:
        selected = None
    try:
        parser = build_parser(selected)
    except ImportError as exc:
        return _torch_missing(selected, exc)
    args = parser.parse_args(args_list)
    if args.command is None:
        parser.print_help()
        return 2
    module = dict((n, m) for n, m, _ in COMMANDS)[args.command]
    try:
        return _load(module).run(args)
    except ImportError as exc:
        return _torch_missing(args.command, exc)
    except RetargetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (``inspect DIR | head``): not an error worth a traceback. Point
        # stdout at /dev/null so the interpreter's final flush does not raise again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
