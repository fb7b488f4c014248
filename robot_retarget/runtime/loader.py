"""Find a model for the live path by name or path, without torch when a runtime file exists.

Order: the built-in baselines (``copy``, ``copy-scaled``); a shipped runtime
(``robot_retarget/data/checkpoints/<name>.npz``); a ``.npz`` path. Anything else — a torch
checkpoint, a training run folder, a shipped name with no runtime file — is loaded through torch
(:func:`robot_retarget.nn.inference.load_model`, imported only then), and its numpy runtime is
used when its architecture has one.
"""

from __future__ import annotations

import dataclasses
import os
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy.typing as npt

from robot_retarget.npz_errors import is_numpy_archive
from robot_retarget.runtime.model import (
    MODEL_FORMS,
    OnlineStep,
    RuntimeModel,
    load_runtime,
    no_foot_lock_error,
    not_a_model,
)
from robot_retarget.skeleton.foot_lock_spec import CONTACT_FPS

if TYPE_CHECKING:
    from robot_retarget.nn.inference import LoadedModel
    from robot_retarget.nn.models.base import RetargetModel

CHECKPOINT_DIR = Path(__file__).resolve().parents[1] / "data" / "checkpoints"
BUILTIN_RUNTIMES: tuple[str, ...] = ("copy", "copy-scaled")


def shipped_runtimes(directory: Path | None = None) -> dict[str, Path]:
    """Runtime files shipped with the package, by name."""
    d = CHECKPOINT_DIR if directory is None else directory
    return {p.stem: p for p in sorted(d.glob("*.npz"))} if d.is_dir() else {}


KEYPOINT_MODEL_PREFIX = "agnostic2d"
"""The shipped keypoint models' names start so (agnostic2d, agnostic2d_clip…): they lift 2D
keypoints for --keypoint-model and are no retargeting model."""


def _shipped_checkpoint_names() -> set[str]:
    """The torch checkpoints shipped with the package (they load only with torch)."""
    return {p.stem for p in CHECKPOINT_DIR.glob("*.pt")} if CHECKPOINT_DIR.is_dir() else set()


def names_runtime_file(text: str) -> bool:
    """``text`` names an exported numpy runtime file: by content, then by name (a torch
    checkpoint named .npz is a zip of its own kind, and the runtime reader names what is wrong
    with any other .npz: missing, cut off)."""
    return is_numpy_archive(Path(text)) or (text.endswith(".npz") and not zipfile.is_zipfile(text))


def load_runtime_model(name_or_path: str | os.PathLike[str]) -> RuntimeModel | LoadedModel:
    """The model to stream with: a numpy :class:`RuntimeModel` whenever one exists, else the
    torch model (which needs torch installed: ``pip install robot-retarget[train]``)."""
    text = os.fspath(name_or_path)
    if text in BUILTIN_RUNTIMES:
        return RuntimeModel(name=text, architecture=text)
    shipped = shipped_runtimes()
    if text in shipped:
        model = load_runtime(shipped[text])
        return dataclasses.replace(model, name=text)
    from robot_retarget.errors import ModelLoadError

    kind = not_a_model(Path(text))
    if kind is not None:  # before torch reads it and fails in its own words
        raise ModelLoadError(
            f"{kind}, not a model: give --model {MODEL_FORMS}", path=text, model=text
        )
    if names_runtime_file(text):
        # Named as given: the file's own record names the checkpoint it was exported from
        # ("best"), which says nothing of exp/walk.npz.
        return dataclasses.replace(load_runtime(text), name=text)
    try:
        from robot_retarget.nn.inference import load_model
    except ImportError as exc:
        where = Path(text).expanduser()
        if not where.exists() and text not in _shipped_checkpoint_names():
            # Torch would not find it either: say so, not that torch is missing.
            names = sorted(
                n for n in {*BUILTIN_RUNTIMES, *shipped} if not n.startswith(KEYPOINT_MODEL_PREFIX)
            )
            if len(where.parts) > 1 or where.suffix in (".pt", ".npz"):
                raise ModelLoadError(f"{text}: no such file or folder", model=text) from None
            raise ModelLoadError(
                f"no model {text!r}: not a model name, nor a file or folder; available names "
                f"here: {', '.join(names)} (or pass a runtime .npz written by export)",
                model=text,
            ) from None
        raise ModelLoadError(
            f"model {text!r} has no numpy runtime file and torch is not installed ({exc}); "
            "install torch (pip install robot-retarget[train]) or export the checkpoint with "
            "`robot-retarget export` where torch is",
            model=text,
        ) from None
    loaded = load_model(text, runtime_files=True)
    return runtime_of(loaded) or loaded


def runtime_of(loaded: LoadedModel) -> RuntimeModel | None:
    """The numpy runtime of a loaded torch model (its provenance kept), or None if its
    architecture has none (NKN, a PMnet with centred convolutions)."""
    runtime = loaded.model.runtime()
    if runtime is None:
        return None
    return dataclasses.replace(
        runtime,
        name=loaded.name,
        path=loaded.path,
        data_hash=loaded.data_hash,
        metadata=dict(loaded.metadata),
    )


def online_retargeter(
    model: RuntimeModel | LoadedModel | RetargetModel,
    source_offsets: npt.ArrayLike,
    target_offsets: npt.ArrayLike,
    *,
    frame_rate_hz: float = CONTACT_FPS,
    foot_lock: bool | None = None,
) -> OnlineStep:
    """The live network step for ``model``, run at ``frame_rate_hz``: its numpy runtime when
    it has one (chosen by the model, :meth:`RetargetModel.runtime`), else the torch model
    stepped frame by frame (which judges speeds at the 30 fps it was trained at).
    ``foot_lock``: as :meth:`RuntimeModel.online` (None: as the model was trained)."""
    if isinstance(model, RuntimeModel):
        return model.online(
            source_offsets, target_offsets, frame_rate_hz=frame_rate_hz, foot_lock=foot_lock
        )
    from robot_retarget.nn.inference import LoadedModel, OnlineRetargeter

    net = model.model if isinstance(model, LoadedModel) else model
    runtime = net.runtime()
    if runtime is not None:
        return runtime.online(
            source_offsets, target_offsets, frame_rate_hz=frame_rate_hz, foot_lock=foot_lock
        )
    if foot_lock:  # only the residual model has a lock, and it always has a runtime
        name = model.name if isinstance(model, LoadedModel) else type(model).__name__
        raise no_foot_lock_error(name)
    return OnlineRetargeter(model, source_offsets, target_offsets)


def check_foot_lock(model: RuntimeModel | LoadedModel, *, foot_lock: bool) -> None:
    """Refuse a foot lock asked of a model without one (before any work: a folder's first
    clip, every worker), naming the model."""
    if not foot_lock:
        return
    runtime = model if isinstance(model, RuntimeModel) else model.model.runtime()
    if runtime is None or not runtime.has_foot_lock:
        raise no_foot_lock_error(model.name, model.path)
