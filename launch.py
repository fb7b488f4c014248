#!/usr/bin/env python3
"""Thin entry point: ``python launch.py <command> ...`` (same CLI as ``robot-retarget``)."""

from robot_retarget.cli.main import main

if __name__ == "__main__":
    raise SystemExit(main())
