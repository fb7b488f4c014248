"""``export``: a trained checkpoint → its numpy runtime file, to stream and convert without torch.

``python launch.py export runs/r6/best.pt --out my_model.npz``; the shipped
``robot_retarget/data/checkpoints/default.npz`` is made by
``python launch.py export robot_retarget/data/checkpoints/default.pt --force``.
"""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path

NAME = "export"
HELP = "Export a trained checkpoint to its numpy runtime (.npz): stream without torch."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("checkpoint", help="a .pt checkpoint, a training run folder or a name")
    parser.add_argument("--out", type=Path, help="runtime file (default: beside it, .npz)")
    parser.add_argument("--force", action="store_true", help="replace an existing file")


def run(args: argparse.Namespace) -> int:
    from robot_retarget.errors import ModelLoadError, MotionFormatError
    from robot_retarget.nn.agnostic2d_training import (
        export_keypoint_checkpoint,
        is_keypoint_checkpoint,
    )
    from robot_retarget.nn.inference import load_model
    from robot_retarget.runtime.loader import runtime_of
    from robot_retarget.runtime.model import load_runtime, save_runtime

    if is_keypoint_checkpoint(args.checkpoint):  # the 2D keypoint model (agnostic2d)
        src = Path(args.checkpoint)
        written = export_keypoint_checkpoint(src, args.out, force=args.force)
        print(f"exported {src} (agnostic2d) → {written} ({written.stat().st_size} bytes)")
        return 0
    loaded = load_model(args.checkpoint)
    runtime = runtime_of(loaded)
    if runtime is None:
        raise ModelLoadError(
            f"architecture {loaded.architecture!r} has no numpy runtime yet; stream it with "
            "torch installed (the checkpoint itself works as --model)",
            model=args.checkpoint,
        )
    if loaded.path is None:
        raise ModelLoadError("built-in models need no export: use them by name", model=loaded.name)
    out: Path = args.out or loaded.path.with_suffix(".npz")
    if out.suffix != ".npz":
        raise MotionFormatError("the runtime file must end in .npz", path=out)
    if out.exists() and not args.force:
        raise MotionFormatError("already exists; pass --force to replace it", path=out)
    digest = hashlib.sha256(loaded.path.read_bytes()).hexdigest()
    stem = loaded.path.stem if loaded.name == str(loaded.path) else loaded.name
    runtime = type(runtime)(**{**runtime.__dict__, "name": stem, "checkpoint_sha256": digest})
    tmp = out.with_name(f".{out.name}.tmp")
    save_runtime(runtime, tmp)
    load_runtime(tmp)  # refuse to leave a file that does not load back
    tmp.replace(out)
    print(f"exported {loaded.path} ({runtime.architecture}) → {out} ({out.stat().st_size} bytes)")
    return 0
