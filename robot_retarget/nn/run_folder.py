"""What a training run leaves in its folder, and clearing it for ``train --force``."""

from __future__ import annotations

from pathlib import Path

RUN_FILES = (
    "config.json", "log.csv", "best.pt", "best.npz", "last.pt", "last.npz", "trainer_state.pt",
)  # fmt: skip
"""Written by robot_retarget.nn.train and agnostic2d_training (and TensorBoard's event files,
``events.out.tfevents.*``, by robot_retarget.nn.train_log)."""


def run_files(out: Path) -> list[Path]:
    """The files of a run in ``out`` (none if it is missing or holds none)."""
    held = [out / name for name in RUN_FILES if (out / name).exists()]
    return held + sorted(out.glob("events.out.tfevents.*"))


def clear_run(out: Path) -> None:
    """Delete a run's files from ``out`` (anything else there stays)."""
    for path in run_files(out):
        path.unlink()
