"""``export``: a trained checkpoint → its numpy runtime file, to stream and convert without torch.

``python launch.py export runs/r6/best.pt --out my_model.npz``; the shipped
``robot_retarget/data/checkpoints/default.npz`` is made by
``python launch.py export robot_retarget/data/checkpoints/default.pt --force``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "export"
HELP = "Export a trained checkpoint to its numpy runtime (.npz): stream without torch."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("checkpoint", help="a .pt checkpoint, a training run folder or a name")
    parser.add_argument("--out", type=Path, help="runtime file (default: beside it, .npz)")
    parser.add_argument("--force", action="store_true", help="replace an existing file")


def run(args: argparse.Namespace) -> int:
    from robot_retarget.nn.agnostic2d_training import (
        export_keypoint_checkpoint,
        is_keypoint_checkpoint,
    )
    from robot_retarget.nn.export import export_runtime

    if is_keypoint_checkpoint(args.checkpoint):  # the 2D keypoint model (agnostic2d)
        src = Path(args.checkpoint)
        written = export_keypoint_checkpoint(src, args.out, force=args.force)
        print(f"exported {src} (agnostic2d) → {written} ({written.stat().st_size} bytes)")
        return 0
    out, architecture = export_runtime(args.checkpoint, args.out, force=args.force)
    print(f"exported {args.checkpoint} ({architecture}) → {out} ({out.stat().st_size} bytes)")
    return 0
