"""CasADi functions for the hot paths: JIT compile and disk cache, and in-place evaluation.

- **Compile and cache.** Functions are compiled with the system C compiler (``-O1``) into
  shared libraries in ``$ROBOT_RETARGET_CACHE`` or ``~/.cache/robot_retarget``; a saved
  function links its library by path, so loading writes no files. The optimizer's solvers
  (:mod:`robot_retarget.optimize.solver`) and the live path's compiled steps share this.
- **Compiled per-frame steps.** On a few hundred numbers numpy spends its time in per-call
  overhead, not arithmetic (a 22×4 sum costs ~2 µs, the same as a 256×256 matrix–vector
  product). The geometric parts of the live path's per-frame steps (quaternion products,
  logarithms, forward kinematics: :mod:`robot_retarget.geometry.symbolic_quaternion`) are
  therefore written once as SX graphs and evaluated in one call each (:func:`compile_graph`:
  compiled to straight-line C and cached, keyed by a hash of the serialized graph and the casadi
  version, or interpreted where a compile per graph would not pay). Without a C compiler a graph
  runs in casadi's virtual machine (≈ 3× slower, still one call), with a logged warning. Dense
  layers stay in numpy, whose BLAS is faster than generated loops.
- **In-place evaluation** (:class:`CompiledFunction`, also under the solvers' BufferedSolver):
  ``Function.buffer()`` binds numpy arrays as arguments and results once, so a call marshals
  nothing. Functions may share arrays (one's result bound as the next one's argument), which is
  how a step chains its stages without copies. Graph inputs and outputs are column vectors; a
  C-ordered numpy array of any shape with that many elements binds to one (row-major (J, 4) is
  index 4·j + c).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import os
import shutil
import tempfile
from collections import OrderedDict
from collections.abc import Callable, Hashable, Mapping, Sequence
from pathlib import Path
from typing import Any, ParamSpec

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray

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


class CompiledFunction:
    """``fn`` bound to numpy arrays: write :attr:`args`, call, read :attr:`res`.

    ``args`` / ``res`` may pass arrays to bind (float64, C-contiguous, the graph's size): a
    result array shared as another function's argument. Missing ones are allocated.
    """

    def __init__(
        self,
        fn: ca.Function,
        *,
        args: Sequence[FloatArray | None] | None = None,
        res: Sequence[FloatArray | None] | None = None,
    ) -> None:
        self.function = fn
        self.args = _bind_arrays("argument", fn, fn.n_in(), fn.nnz_in, args)
        self.res = _bind_arrays("result", fn, fn.n_out(), fn.nnz_out, res)
        self._buffer, self._trigger = fn.buffer()
        # casadi's stub says set_arg(i, buffer, size); the binding takes (i, buffer).
        buffer: Any = self._buffer
        for i, a in enumerate(self.args):
            buffer.set_arg(i, a.data)
        for i, a in enumerate(self.res):
            buffer.set_res(i, a.data)

    def __call__(self) -> None:
        self._trigger()


def _bind_arrays(
    kind: str,
    fn: ca.Function,
    count: int,
    nnz: Any,
    given: Sequence[FloatArray | None] | None,
) -> list[FloatArray]:
    if given is not None and len(given) != count:
        raise ValueError(f"{fn.name()} has {count} {kind}s, got {len(given)} arrays")
    out: list[FloatArray] = []
    for i in range(count):
        a = None if given is None else given[i]
        if a is None:
            out.append(np.zeros(nnz(i)))
            continue
        if a.dtype != np.float64 or not a.flags.c_contiguous or a.size != nnz(i):
            raise ValueError(
                f"{fn.name()} {kind} {i} needs a C-contiguous float64 array of {nnz(i)} "
                f"values, got {a.dtype} {a.shape}"
            )
        out.append(a)
    return out


def compile_graph(
    name: str,
    inputs: Sequence[ca.SX],
    outputs: Sequence[ca.SX],
    *,
    jit: bool = True,
    cache_dir: Path | None = None,
) -> ca.Function:
    """The SX function ``inputs → outputs``, JIT-compiled (loaded from the cache when built
    before) or, without a C compiler or with ``jit=False``, interpreted."""
    fn = ca.Function(name, list(inputs), list(outputs))
    if not jit:
        return fn
    cache = cache_dir or default_cache_dir()
    path = cache / f"{name}-{_graph_key(fn)}.casadi"
    # One load per process and file: every performer's step shares the compiled function.
    loaded = _LOADED.get(path)
    if loaded is None:
        loaded = _LOADED[path] = _load_or_compile(fn, path)
    return loaded


_LOADED: dict[Path, ca.Function] = {}


def _load_or_compile(fn: ca.Function, path: Path) -> ca.Function:
    compiled = load_or_jit(
        path,
        lambda opts: ca.Function(fn.name(), fn.sx_in(), fn.call(fn.sx_in()), opts),
        without=f"the live step {fn.name()} runs interpreted, about 3x slower",
    )
    return fn if compiled is None else compiled


def load_or_jit(
    path: Path,
    build: Callable[[dict[str, Any]], ca.Function],
    *,
    without: str,
    compiler: str | None = None,
) -> ca.Function | None:
    """The function saved at ``path``, else ``build(jit options)`` compiled with ``compiler``
    (default gcc/cc) and saved there; None, with a warning that says ``without`` (what runs
    instead), where there is no compiler or the compile fails."""
    if path.is_file():
        try:
            return ca.Function.load(str(path))
        except RuntimeError as exc:  # stale or truncated file: rebuild below
            log.warning("ignoring unreadable cache file %s: %s", path, exc)
    cc = find_compiler(compiler)
    if cc is None:
        log.warning(
            "no C compiler found (%s): %s; install gcc to speed it up",
            compiler or "gcc/cc",
            without,
        )
        return None
    lib_name = f"{path.stem.replace('-', '_')}_{os.getpid()}"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fn = build(jit_options(cc, path.parent, lib_name))
    except (RuntimeError, OSError) as exc:
        log.warning("JIT compilation with %s failed (%s): %s", cc, without, exc)
        return None
    finally:
        # casadi 3.8 leaves the generated C file in the working directory.
        with contextlib.suppress(OSError):
            (Path.cwd() / f"{lib_name}.c").unlink(missing_ok=True)
    save_function(fn, path)
    return fn


P = ParamSpec("P")
_MEMO_SIZE = 64


def memoized_graph(build: Callable[P, ca.Function]) -> Callable[P, ca.Function]:
    """``build`` run once per distinct arguments (numpy arrays compared by content), the last
    64 kept. An SX graph of a few thousand operations takes ~0.2 s to build in Python, and its
    callers ask for the same one per clip, per corruption kind, per model."""
    cache: OrderedDict[Hashable, ca.Function] = OrderedDict()

    @functools.wraps(build)
    def cached(*args: P.args, **kwargs: P.kwargs) -> ca.Function:
        key = (_freeze(args), _freeze(kwargs))
        fn = cache.get(key)
        if fn is None:
            fn = cache[key] = build(*args, **kwargs)
            if len(cache) > _MEMO_SIZE:
                cache.popitem(last=False)
        else:
            cache.move_to_end(key)
        return fn

    return cached


def _freeze(x: object) -> Hashable:
    if isinstance(x, np.ndarray):
        return ("ndarray", x.shape, x.dtype.str, x.tobytes())
    if isinstance(x, Mapping):
        return tuple(sorted((k, _freeze(v)) for k, v in x.items()))
    if isinstance(x, (list, tuple)):
        return tuple(_freeze(v) for v in x)
    return x


def _graph_key(fn: ca.Function) -> str:
    h = hashlib.sha256()
    h.update(fn.serialize().encode())
    h.update(str(ca.CasadiMeta.version()).encode())
    return h.hexdigest()[:20]
