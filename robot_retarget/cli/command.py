"""The shape every CLI command module has: a name, a one-line help, argument setup and a run."""

from __future__ import annotations

import argparse
from typing import Protocol


class Command(Protocol):
    """A module in ``robot_retarget.cli`` implementing one sub-command."""

    NAME: str
    HELP: str

    def configure(self, parser: argparse.ArgumentParser) -> None:
        """Add the command's arguments."""

    def run(self, args: argparse.Namespace) -> int:
        """Do the work; return the process exit code."""
