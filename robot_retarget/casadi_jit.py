"""CasADi's JIT compile settings and on-disk cache, shared by the optimizer's solvers
(:mod:`robot_retarget.optimize.solver`) and the live path's compiled steps
(:mod:`robot_retarget.runtime.compiled_function`).

Functions are compiled with the system C compiler (``-O1``) into shared libraries in
``$ROBOT_RETARGET_CACHE`` or ``~/.cache/robot_retarget``; a saved function links its library by
path, so loading writes no files.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import casadi as ca

log = logging.getLogger(__name__)

CACHE_ENV = "ROBOT_RETARGET_CACHE"


def default_cache_dir() -> Path:
    """``$ROBOT_RETARGET_CACHE`` or ``~/.cache/robot_retarget``."""
    env = os.environ.get(CACHE_ENV)
    return Path(env) if env else Path.home() / ".cache" / "robot_retarget"


def find_compiler(name: str | None = None) -> str | None:
    """Path of a C compiler (``name``, else gcc, else cc), or None when there is none."""
    for candidate in (name,) if name else ("gcc", "cc"):
        path = shutil.which(candidate)
        if path:
            return path
    return None


def jit_options(compiler: str, directory: Path, name: str) -> dict[str, Any]:
    return {
        "jit": True,
        "compiler": "shell",
        "jit_name": name,
        "jit_temp_suffix": False,
        "jit_cleanup": False,  # see the stray C file below
        "jit_options": {
            "compiler": compiler,
            "flags": ["-O1"],  # -O2 compiles ≈ 3× longer for no measurable speed-up here
            "verbose": False,
            "directory": f"{directory}{os.sep}",
            "name": name,
            "temp_suffix": False,
            "cleanup": False,  # the saved solver links this library: keep it
        },
        # The saved solver refers to the library by path: loading writes no files.
        "jit_serialize": "link",
    }


def save_function(solver: ca.Function, path: Path) -> None:
    """Write atomically, so a concurrent reader never sees half a file."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        os.close(fd)
        solver.save(tmp)
        os.replace(tmp, path)
    except (OSError, RuntimeError) as exc:  # a read-only cache only costs the next start time
        log.warning("could not cache the compiled solver at %s: %s", path, exc)
