"""``export``: a trained checkpoint → its numpy runtime file, to stream and convert without torch.

``python launch.py export runs/r6/best.pt --out my_model.npz``; the shipped
``robot_retarget/data/checkpoints/default.npz`` is made by
``python launch.py export robot_retarget/data/checkpoints/default.pt --force``. Several
keypoint-model checkpoints make one ensemble runtime whose answers are averaged (the shipped
``agnostic2d_clip.npz``, see the README's "Video input").
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "export"
HELP = "Export a trained checkpoint to its numpy runtime (.npz): stream without torch."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "checkpoint",
        nargs="+",
        help="a .pt checkpoint, a training run folder or a name; several agnostic2d "
        "checkpoints: one ensemble runtime (answers averaged; --out names it)",
    )
    parser.add_argument("--out", type=Path, help="runtime file (default: beside it, .npz)")
    parser.add_argument("--force", action="store_true", help="replace an existing file")


def run(args: argparse.Namespace) -> int:
    from robot_retarget.nn.agnostic2d_training import (
        export_keypoint_checkpoint,
        is_keypoint_checkpoint,
    )
    from robot_retarget.nn.export import export_runtime

    # A training run folder stands for its best checkpoint (either kind of model).
    sources = [
        str(Path(c) / "best.pt") if (Path(c) / "best.pt").is_file() else c for c in args.checkpoint
    ]
    keypoint = [is_keypoint_checkpoint(c) for c in sources]
    if len(sources) > 1:
        missing = [c for c in sources if not Path(c).is_file()]
        if missing:
            raise SystemExit(f"export: no such checkpoint file: {', '.join(missing)}")
        if not all(keypoint):
            others = ", ".join(c for c, k in zip(sources, keypoint, strict=True) if not k)
            raise SystemExit(
                f"export: only agnostic2d checkpoints make an ensemble; not one: {others} "
                "(export a retargeting network's checkpoint on its own)"
            )
        if args.out is None:
            raise SystemExit("export: an ensemble of several checkpoints needs --out FILE.npz")
    if all(keypoint):  # the 2D keypoint model (agnostic2d), one or an ensemble
        paths = [Path(c) for c in sources]
        written = export_keypoint_checkpoint(paths, args.out, force=args.force)
        kind = "agnostic2d" if len(paths) == 1 else f"agnostic2d, ensemble of {len(paths)}"
        print(
            f"exported {', '.join(sources)} ({kind}) → {written} ({written.stat().st_size} bytes)"
        )
        return 0
    out, architecture = export_runtime(sources[0], args.out, force=args.force)
    print(f"exported {sources[0]} ({architecture}) → {out} ({out.stat().st_size} bytes)")
    return 0
