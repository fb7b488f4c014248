"""A trained checkpoint → its numpy runtime file (.npz), which streams and converts without torch.

Used by ``export`` and at the end of ``train`` (beside ``best.pt``, so a run can be streamed on a
robot's computer without installing torch).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from robot_retarget.errors import ModelLoadError, MotionFormatError


def export_runtime(
    checkpoint: str | Path, out: Path | None = None, *, force: bool = False
) -> tuple[Path, str]:
    """Write the runtime of ``checkpoint`` (a .pt file, a run folder or a name) to ``out``
    (default: beside it, .npz); returns (path written, architecture). Raises ModelLoadError when
    the architecture has no numpy runtime, MotionFormatError when ``out`` exists without
    ``force`` or does not end in .npz. The file is written atomically and loaded back first."""
    from robot_retarget.nn.inference import load_model
    from robot_retarget.runtime.loader import runtime_of
    from robot_retarget.runtime.model import load_runtime, save_runtime

    loaded = load_model(checkpoint)
    runtime = runtime_of(loaded)
    if runtime is None:
        raise ModelLoadError(
            f"architecture {loaded.architecture!r} has no numpy runtime yet; stream it with "
            "torch installed (the checkpoint itself works as --model)",
            model=str(checkpoint),
        )
    if loaded.path is None:
        raise ModelLoadError("built-in models need no export: use them by name", model=loaded.name)
    target = out or loaded.path.with_suffix(".npz")
    if target.suffix != ".npz":
        raise MotionFormatError("the runtime file must end in .npz", path=target)
    if target.exists() and not force:
        made_by_train = out is None and target.name == "best.npz"
        raise MotionFormatError(
            "already exists"
            + (" (train writes each run's best.npz itself)" if made_by_train else "")
            + "; pass --force to replace it, or --out to write another file",
            path=target,
        )
    digest = hashlib.sha256(loaded.path.read_bytes()).hexdigest()
    stem = loaded.path.stem if loaded.name == str(loaded.path) else loaded.name
    runtime = type(runtime)(**{**runtime.__dict__, "name": stem, "checkpoint_sha256": digest})
    tmp = target.with_name(f".{target.name}.tmp")
    save_runtime(runtime, tmp)
    load_runtime(tmp)  # refuse to leave a file that does not load back
    tmp.replace(target)
    return target, runtime.architecture
