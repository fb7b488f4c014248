"""Save and load trained retargeting models with what is needed to trust them later.

A checkpoint is one ``torch.save`` file holding plain data only (loaded with
``weights_only=True``, so opening a file cannot run code):

- ``format`` / ``version``: identifies the file; newer versions are refused;
- ``model`` and ``config``: the registry name and constructor arguments that rebuild it;
- ``state_dict``: weights and normalisation statistics;
- ``skeletons``: the skeleton set it was trained for (name → rest offsets (J, 3), metres);
- ``data_hash``: a fingerprint of the training data (:func:`fingerprint`);
- ``metadata``: anything else JSON-like (epochs, losses, command line).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.registry import build_model, model_class
from robot_retarget.npz_errors import is_numpy_archive

FORMAT = "robot-retarget-model"
VERSION = 1


@dataclass(frozen=True)
class LoadedCheckpoint:
    """A rebuilt model (in eval mode) and the facts stored with it."""

    model: RetargetModel
    skeletons: dict[str, npt.NDArray[np.float64]]
    data_hash: str
    metadata: dict[str, Any] = field(default_factory=dict)


def fingerprint(arrays: Iterable[npt.ArrayLike]) -> str:
    """SHA-256 (hex) over arrays' shapes, dtypes and bytes, in order: a training-data hash."""
    h = hashlib.sha256()
    for a in arrays:
        arr = np.ascontiguousarray(a)
        h.update(f"{arr.dtype.str}{arr.shape}".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def save_checkpoint(
    path: str | Path,
    model: RetargetModel,
    *,
    skeletons: Mapping[str, npt.ArrayLike] | None = None,
    data_hash: str = "",
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``model`` to ``path`` atomically (temporary file, then rename); returns the path."""
    target = Path(path)
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "model": model.name,
        "config": dict(model.config()),
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "skeletons": {
            name: torch.tensor(np.array(offs, dtype=np.float64))
            for name, offs in (skeletons or {}).items()
        },
        "data_hash": data_hash,
        "metadata": dict(metadata or {}),
    }
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, target)
    return target


def foreign_file(path: Path) -> str | None:
    """What ``path`` is, where it is plainly not a checkpoint: a folder, or a motion or text
    file (torch's own error for those is a paragraph about pickles); else None."""
    if path.is_dir():
        return "a folder, not a checkpoint file"
    try:
        with path.open("rb") as f:
            head = f.read(64).lstrip()
    except OSError:
        return None
    if head.upper().startswith(b"HIERARCHY"):
        return "a BVH motion clip, not a checkpoint"
    if is_numpy_archive(path):
        return (
            "a numpy (.npz) archive, such as an exported runtime file (convert, stream and the "
            "API take those as --model), not a checkpoint"
        )
    if head[:1] in (b"{", b"["):
        return "a JSON file, not a checkpoint"
    return None


def unreadable_reason(exc: BaseException) -> str:
    """torch.load's failure in one short line (its messages run to paragraphs)."""
    lines = str(exc).strip().splitlines()
    first = lines[0] if lines else ""
    if len(first) > 120:
        first = first[:117] + "…"
    return f"{type(exc).__name__}: {first}" if first else type(exc).__name__


def load_checkpoint(path: str | Path, *, expected_data_hash: str | None = None) -> LoadedCheckpoint:
    """Rebuild a model from ``path``; raises ModelLoadError saying what is wrong with the file."""
    source = Path(path)
    foreign = foreign_file(source)
    if foreign is not None:
        raise ModelLoadError(f"{foreign}; pass a .pt file written by train", path=source)
    if not source.is_file():
        raise ModelLoadError(
            "no such checkpoint file; check the path or train a model first", path=source
        )
    try:
        payload = torch.load(source, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for foreign or damaged files
        raise ModelLoadError(
            f"not a readable checkpoint ({unreadable_reason(exc)}); was it written by "
            "robot-retarget's train (a .pt file) and copied completely?",
            path=source,
        ) from exc
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ModelLoadError(
            f"not a robot-retarget model checkpoint (no format {FORMAT!r} marker)", path=source
        )
    version = payload.get("version")
    if not isinstance(version, int) or version > VERSION:
        raise ModelLoadError(
            f"checkpoint version {version!r} is newer than this robot-retarget reads "
            f"({VERSION}); upgrade robot-retarget",
            path=source,
        )
    missing = [k for k in ("model", "config", "state_dict") if k not in payload]
    if missing:
        raise ModelLoadError(f"checkpoint lacks {', '.join(missing)}", path=source)
    name = payload["model"]
    try:
        model = build_model(name, **model_class(name).upgrade_config(dict(payload["config"])))
    except ModelLoadError as exc:
        raise ModelLoadError(str(exc), path=source, model=name) from exc
    try:
        model.load_state_dict(payload["state_dict"], strict=True)
    except RuntimeError as exc:
        raise ModelLoadError(
            f"weights do not fit model {name!r} with config {payload['config']!r}: {exc}",
            path=source,
            model=name,
        ) from exc
    data_hash = str(payload.get("data_hash", ""))
    if expected_data_hash is not None and data_hash != expected_data_hash:
        raise ModelLoadError(
            f"checkpoint was trained on data {data_hash[:12] or '<unknown>'}…, expected "
            f"{expected_data_hash[:12]}…; retrain or pass the matching data",
            path=source,
            model=name,
        )
    model.eval()
    skeletons = {
        str(k): np.asarray(v.numpy(), dtype=np.float64)
        for k, v in dict(payload.get("skeletons", {})).items()
    }
    return LoadedCheckpoint(
        model=model,
        skeletons=skeletons,
        data_hash=data_hash,
        metadata=dict(payload.get("metadata", {})),
    )
