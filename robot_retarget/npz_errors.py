"""Why ``np.load`` refused a file, in words for the user; and whether a file is numpy's archive
whatever its name says.

numpy answers a file that is not a zip archive (a text file renamed ``.npz``, a cut-off
download) with advice to load it with ``allow_pickle=True`` — loading untrusted pickles runs
their code, so that advice must never reach a user. Every ``.npz`` this project reads is
opened with ``allow_pickle=False``; this says what is wrong instead.
"""

from __future__ import annotations

import zipfile
from pathlib import Path


def npz_unreadable_reason(exc: BaseException) -> str:
    """One line for ``np.load``'s failure on an ``.npz``."""
    if isinstance(exc, zipfile.BadZipFile) or "pickle" in str(exc).lower():
        return "not an .npz (zip) archive: cut off, or not written by numpy"
    if isinstance(exc, EOFError):
        return "the file ends early: cut off while being written or copied"
    return f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}".rstrip(": ")


def is_numpy_archive(path: Path) -> bool:
    """``path`` is an ``.npz`` archive by its content (a zip of top-level ``.npy`` members),
    whatever its suffix: a torch checkpoint is a zip too, but of a folder with ``data.pkl``."""
    try:
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
    except (OSError, zipfile.BadZipFile):
        return False
    return bool(names) and all(n.endswith(".npy") and "/" not in n for n in names)
