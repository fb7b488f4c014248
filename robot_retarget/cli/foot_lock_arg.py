"""``--foot-lock``, shared by the commands that drive the robot (convert, stream, eval-robot,
the pipeline benchmarks)."""

from __future__ import annotations

import argparse

FOOT_LOCK_HELP = (
    "run the residual network's foot lock (it holds a planted foot still on the network's own "
    "output skeleton). Off on the robot by default: cross-validated, it moves the robot 0.04-0.16 "
    "deg further from the performer and adds 8-20 %% of jerk; models without a lock refuse it"
)


def add_foot_lock_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--foot-lock", action="store_true", help=FOOT_LOCK_HELP)
