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

from robot_retarget.cli.output_paths import Output, check_outputs
from robot_retarget.errors import ModelLoadError

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

    sources = [_checkpoint_file(c) for c in args.checkpoint]
    if args.out is None and Path(sources[0]).suffix.lower() == ".npz":
        # The default --out is the checkpoint's own name with .npz: --force would replace it.
        raise ModelLoadError(
            f"{sources[0]}: a checkpoint named .npz would be exported onto itself (the runtime "
            "goes beside the checkpoint, named .npz); give --out FILE.npz"
        )
    seen: dict[Path, str] = {}
    for given, source in zip(args.checkpoint, sources, strict=True):
        key = Path(source).resolve()
        if key in seen:
            raise ModelLoadError(
                f"{given}: the same checkpoint as {seen[key]}; an ensemble averages different "
                "models (the same one twice only weighs it double), give each once"
            )
        seen[key] = given
    if args.out is not None:
        check_outputs(
            [Output("--out", args.out, (".npz",))],
            inputs=[Path(c) for c in sources if Path(c).is_file()],
            force=args.force,
        )
    keypoint = [is_keypoint_checkpoint(c) for c in sources]
    if len(sources) > 1:
        missing = [c for c in sources if not Path(c).is_file()]
        if missing:
            raise ModelLoadError(f"no such checkpoint file: {', '.join(missing)}")
        if not all(keypoint):
            others = ", ".join(c for c, k in zip(sources, keypoint, strict=True) if not k)
            raise ModelLoadError(
                f"only agnostic2d checkpoints make an ensemble; not one: {others} "
                "(export a retargeting network's checkpoint on its own)"
            )
        if args.out is None:
            raise ModelLoadError("an ensemble of several checkpoints needs --out FILE.npz")
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


def _checkpoint_file(given: str) -> str:
    """A run folder stands for its best checkpoint (either kind of model); a runtime file, a
    folder without one or a path that names no file is a one-line error (load_model's rules).
    A bare name (a built-in or shipped model) passes through to the loader."""
    from robot_retarget.nn.inference import checkpoint_file

    path = checkpoint_file(given)
    return given if path is None else str(path)
