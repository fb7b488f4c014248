"""The runtime file: named float arrays and a JSON ``__meta__`` entry in one ``.npz``, read
with ``allow_pickle=False`` so a file from anywhere cannot run code. Every numpy runtime
(retargeting networks, the keypoint model) is written and read through here."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.errors import ModelLoadError
from robot_retarget.npz_errors import npz_unreadable_reason

META_KEY = "__meta__"


def write_runtime_npz(out: Path, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> Path:
    """Write ``arrays`` and ``meta`` (JSON; anything else as its string) to ``out``."""
    entries = dict(arrays)
    entries[META_KEY] = np.array(json.dumps(meta, default=str))
    with out.open("wb") as fh:
        np.savez(fh, allow_pickle=False, **entries)
    return out


def read_runtime_npz(path: Path, what: str) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """(arrays, metadata) of a runtime file; ModelLoadError names ``path`` and what is wrong
    (``what``: how the error calls the file, e.g. "runtime file")."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise ModelLoadError(f"{what} not found", path=path) from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:  # a cut-off file too
        raise ModelLoadError(
            f"not a runtime .npz file ({npz_unreadable_reason(exc)})", path=path
        ) from None
    if META_KEY not in arrays:
        raise ModelLoadError(
            "runtime file has no __meta__ entry (not exported by export)", path=path
        )
    try:
        meta = json.loads(str(arrays.pop(META_KEY)))
    except json.JSONDecodeError as exc:
        raise ModelLoadError(f"runtime metadata is not JSON ({exc})", path=path) from None
    if not isinstance(meta, dict):
        raise ModelLoadError("runtime metadata is not a JSON object", path=path)
    return arrays, meta
