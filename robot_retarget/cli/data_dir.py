"""Where the commands that read the mocap clips (``train``, ``eval``, ``eval-robot``) look by
default: ``$ROBOT_RETARGET_DATA/mocap`` when the variable is set, else ``../shared/data/mocap``
next to the checkout (the tests' convention, tests/conftest.py). ``--data DIR`` overrides both.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

DATA_ENV = "ROBOT_RETARGET_DATA"
"""Environment variable naming the shared data folder (the one holding ``mocap/``)."""

_CHECKOUT_DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def shared_data_dir() -> Path:
    """``$ROBOT_RETARGET_DATA`` when set (and not empty), else ``<checkout>/../shared/data``."""
    value = os.environ.get(DATA_ENV, "")
    return Path(value) if value else _CHECKOUT_DATA


def default_mocap_dir() -> Path:
    """The default ``--data`` folder: :func:`shared_data_dir` / ``mocap``."""
    return shared_data_dir() / "mocap"


def add_data_argument(parser: argparse.ArgumentParser) -> None:
    """``--data DIR``, defaulting to :func:`default_mocap_dir` (read when the parser is built)."""
    default = default_mocap_dir()
    parser.add_argument(
        "--data",
        default=str(default),
        help=f"folder of BVH clips (default: ${DATA_ENV}/mocap if set, else "
        f"../shared/data/mocap; now {default})",
    )
