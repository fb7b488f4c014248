"""``bench TARGET``: speed benchmarks that print median and p99 over many runs.

Each target lives in its own module exposing ``HELP``, ``configure(parser)`` and
``run(args) -> list[BenchRecord]``; this command prints the records as a table, or one JSON
object per line with ``--json``.
"""

from __future__ import annotations

import argparse
import importlib
import json
from typing import Any, Protocol, cast

from robot_retarget.cli.missing_torch import INSTALL_HINT, MissingTorchError, is_missing_torch

NAME = "bench"
HELP = "Speed benchmarks (median and p99): solve, loop, model, pipeline, convert, stream."

BenchRecord = dict[str, Any]

# target name → module implementing it
TARGETS: dict[str, str] = {
    "solve": "robot_retarget.optimize.benchmark",
    "loop": "robot_retarget.hardware.benchmark",
    "model": "robot_retarget.nn.benchmark",
    "pipeline": "robot_retarget.pipeline.benchmark",
    "convert": "robot_retarget.pipeline.convert_benchmark",
    "stream": "robot_retarget.pipeline.stream_benchmark",
}


class BenchTarget(Protocol):
    HELP: str

    def configure(self, parser: argparse.ArgumentParser) -> None: ...

    def run(self, args: argparse.Namespace) -> list[BenchRecord]: ...


def _target(name: str) -> BenchTarget:
    return cast(BenchTarget, importlib.import_module(TARGETS[name]))


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    for name in TARGETS:
        try:
            target = _target(name)
        except ImportError as exc:
            if not is_missing_torch(exc):
                raise
            # The other benchmarks still run; this one says what it needs when it is asked.
            p = sub.add_parser(name, help=f"(needs torch, not installed: {INSTALL_HINT})")
            p.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
            p.set_defaults(missing_torch=str(exc))
            continue
        p = sub.add_parser(name, help=target.HELP, description=target.HELP)
        p.add_argument("--json", action="store_true", help="one JSON object per line")
        target.configure(p)


def format_table(records: list[BenchRecord]) -> str:
    """Fixed-width table with the union of the records' keys as columns."""
    if not records:
        return "(no results)"
    columns: list[str] = []
    for r in records:
        columns.extend(k for k in r if k not in columns)

    def cell(v: Any) -> str:
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    rows = [[cell(r.get(c, "")) for c in columns] for r in records]
    widths = [max(len(c), *(len(row[i]) for row in rows)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True))]
    lines += ["  ".join(v.ljust(w) for v, w in zip(row, widths, strict=True)) for row in rows]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if getattr(args, "missing_torch", None) is not None:
        raise MissingTorchError(f"robot-retarget bench {args.target}", args.missing_torch)
    records = _target(args.target).run(args)
    if args.json:
        for r in records:
            print(json.dumps(r))
    else:
        print(format_table(records))
    return 0
