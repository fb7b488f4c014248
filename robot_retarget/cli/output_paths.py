"""Output files of the CLI: checked before any work starts, written atomically, never lost.

Every command that writes files (convert, stream --record, demo, the previews) goes through
this module:

- :func:`check_outputs` runs before any work (no model loaded, no robot moved). It refuses,
  with a one-line :class:`OutputPathError`: a wrong suffix; an output that is one of the inputs
  (paths resolved, links followed; even with --force); two outputs on the same path; an
  existing output without --force; a folder where a file should go; a folder that is missing
  or not writable. Writability is tested by creating (and removing) a probe file, so read-only
  mounts and permissions are both seen. A *file*'s folder must exist; a *folder* named on the
  command line (``demo --out-dir``, convert's folder outputs) is created when missing, if its
  nearest existing parent is a writable folder.
- :class:`StagedWrites` writes each output to a temporary file in its own folder and moves it
  into place with ``os.replace`` only when every output of the group has been written: a
  failure leaves neither a partial file nor half of a group (the temporaries are removed).
- :func:`save_with_fallback` is for what cannot be recomputed (a live recording): when the
  path that was checked can no longer be written at the end, the file goes to a fallback path
  (a new name in the same folder, else the working folder, else the temporary folder) and the
  caller is told where.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shlex
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

from robot_retarget.errors import RetargetError

Writer = Callable[[Path], object]
"""Writes one output to the path it is given (a temporary path with the output's suffix)."""


class OutputPathError(RetargetError):
    """An output path cannot be used. ``option`` is the command-line option that named it
    (``--out``, ``--record``, ...), ``path`` the file or folder, ``other`` the other path
    involved (the input it would overwrite, the output it collides with), if any."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path,
        option: str = "",
        other: str | Path | None = None,
    ) -> None:
        self.path = str(path)
        self.option = option
        self.other = None if other is None else str(other)
        self.reason = message
        where = f"{option} {self.path}" if option else self.path
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class Output:
    """One output file. ``suffixes``: the allowed suffixes (lower case; empty: any);
    ``make_folders``: its missing folders may be created (it lies under a folder output)."""

    option: str
    path: Path
    suffixes: tuple[str, ...] = ()
    make_folders: bool = False


def _resolve(path: Path) -> Path:
    return Path(os.path.abspath(path)).resolve()


def _inode(path: Path) -> tuple[int, int] | None:
    """(device, inode) of an existing file: catches hard links and case-insensitive names."""
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _probe_writable(folder: Path) -> OSError | None:
    """None when a file can be created in ``folder``; else the error that stopped it."""
    try:
        fd, name = tempfile.mkstemp(prefix=".robot-retarget-probe-", dir=folder)
    except OSError as exc:
        return exc
    os.close(fd)
    os.unlink(name)
    return None


def _nearest_existing(folder: Path) -> Path:
    p = Path(os.path.abspath(folder))
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_folder(folder: Path, *, option: str = "", create: bool = False) -> None:
    """``folder`` exists (or, with ``create``, can be created) and a file can be written in
    it; raises :class:`OutputPathError` otherwise. Creates nothing."""
    _check_folder(folder, option, create, set())


def _check_folder(folder: Path, option: str, create: bool, probed: set[Path]) -> None:
    if folder.exists() and not folder.is_dir():
        raise OutputPathError(
            "is a file, not a folder; choose another path", path=folder, option=option
        )
    target = folder
    if not folder.exists():
        if not create:
            raise OutputPathError(
                f"no such folder; create it first (mkdir -p {shlex.quote(str(folder))}) or "
                "choose another path",
                path=folder,
                option=option,
            )
        target = _nearest_existing(folder)
        if not target.is_dir():
            raise OutputPathError(
                f"cannot create the folder {folder}: {target} is a file",
                path=folder,
                option=option,
            )
    key = _resolve(target)
    if key in probed:
        return
    problem = _probe_writable(target)
    if problem is not None:
        reason = problem.strerror or str(problem)
        if problem.errno == errno.ENOENT and target.is_dir():
            # It exists, yet creating a file in it says "no such file": a virtual file system.
            reason = "no file can be created in it: a virtual file system such as /proc or /sys"
        where = "" if target == folder else f" (its nearest existing parent {target})"
        raise OutputPathError(
            f"the folder{where} is not writable ({reason}); choose a writable folder",
            path=folder,
            option=option,
        )
    probed.add(key)


def check_outputs(
    outputs: Sequence[Output], *, inputs: Iterable[Path] = (), force: bool = False
) -> None:
    """Check every output before any work starts (see the module docstring); raises
    :class:`OutputPathError` naming the option, the path and, where two paths clash, both."""
    by_path: dict[Path, Path] = {}
    by_inode: dict[tuple[int, int], Path] = {}
    for src in inputs:
        by_path.setdefault(_resolve(src), src)
        node = _inode(src)
        if node is not None:
            by_inode.setdefault(node, src)
    for out in outputs:
        node = _inode(out.path)
        clash = by_path.get(_resolve(out.path)) or (by_inode.get(node) if node else None)
        if clash is not None:
            raise OutputPathError(
                f"is the input {clash} itself; an output never replaces an input (not even "
                "with --force): choose another output path",
                path=out.path,
                option=out.option,
                other=clash,
            )
    out_by_path: dict[Path, Output] = {}
    out_by_inode: dict[tuple[int, int], Output] = {}
    for out in outputs:
        key = _resolve(out.path)
        node = _inode(out.path)
        prev = out_by_path.get(key) or (out_by_inode.get(node) if node else None)
        if prev is not None:
            raise OutputPathError(
                f"is also the output of {prev.option} {prev.path}; give each output its own path",
                path=out.path,
                option=out.option,
                other=prev.path,
            )
        out_by_path[key] = out
        if node is not None:
            out_by_inode[node] = out
    for out in outputs:
        if out.suffixes and out.path.suffix.lower() not in out.suffixes:
            raise OutputPathError(
                f"must end in {', '.join(out.suffixes)}, got {out.path.suffix or '(none)'!r}",
                path=out.path,
                option=out.option,
            )
    for out in outputs:
        if out.path.is_dir():
            raise OutputPathError("is a folder; give a file name", path=out.path, option=out.option)
    existing = [o for o in outputs if o.path.exists()]
    if existing and not force:
        more = f" (and {len(existing) - 1} more output(s))" if len(existing) > 1 else ""
        raise OutputPathError(
            f"already exists{more}; pass --force to replace it, or choose another path",
            path=existing[0].path,
            option=existing[0].option,
        )
    probed: set[Path] = set()
    for out in outputs:
        _check_folder(out.path.parent, out.option, out.make_folders, probed)


def _temp_path(path: Path) -> Path:
    """A fresh hidden name next to ``path`` that keeps its suffix (writers choose the format
    by suffix)."""
    return path.with_name(f".{path.stem}-{secrets.token_hex(4)}.tmp{path.suffix}")


def _remove_temps(tmp: Path) -> None:
    """Remove ``tmp`` and any temporaries a writer derived from it (``NAME.part``, ...)."""
    prefix = tmp.stem
    try:
        names = [p for p in tmp.parent.iterdir() if p.name.startswith(prefix)]
    except OSError:
        return
    for p in names:
        with contextlib.suppress(OSError):
            p.unlink()


class StagedWrites:
    """Write a group of outputs to temporary files, then move them all into place.

    ``with StagedWrites(force=...) as stage: stage.write(path, writer, option=...)``: on a
    normal exit every output is moved into place (os.replace); on an exception (or
    :meth:`discard`) every temporary is removed and nothing is replaced. A write that fails is
    raised as :class:`OutputPathError`. ``make_folders``: create the output's missing folders
    (outputs under a folder output); otherwise its folder must exist.
    """

    def __init__(self, *, force: bool = False) -> None:
        self.force = force
        self._staged: list[tuple[Path, Path, str]] = []

    def write(
        self, path: Path, writer: Writer, *, option: str = "", make_folders: bool = False
    ) -> None:
        tmp = _temp_path(path)
        try:
            if make_folders:
                path.parent.mkdir(parents=True, exist_ok=True)
            writer(tmp)
            if not tmp.is_file():
                raise OSError(f"the writer left no file at {tmp}")
        except OSError as exc:
            _remove_temps(tmp)
            raise OutputPathError(
                f"cannot write it: {exc.strerror or exc}", path=path, option=option
            ) from exc
        except BaseException:
            _remove_temps(tmp)
            raise
        self._staged.append((tmp, path, option))

    def commit(self) -> list[Path]:
        """Move every staged output into place; returns their paths."""
        staged, self._staged = self._staged, []
        if not self.force:
            for _tmp, path, option in staged:
                if path.exists():
                    for t, _, _ in staged:
                        _remove_temps(t)
                    raise OutputPathError(
                        "appeared while it was being computed; pass --force to replace it",
                        path=path,
                        option=option,
                    )
        done: list[Path] = []
        try:
            for tmp, path, option in staged:
                try:
                    os.replace(tmp, path)
                except OSError as exc:
                    raise OutputPathError(
                        f"cannot write it: {exc.strerror or exc}", path=path, option=option
                    ) from exc
                done.append(path)
        finally:
            for tmp, _, _ in staged:
                _remove_temps(tmp)
        return done

    def discard(self) -> None:
        staged, self._staged = self._staged, []
        for tmp, _, _ in staged:
            _remove_temps(tmp)

    def __enter__(self) -> StagedWrites:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def write_atomic(
    path: Path,
    writer: Writer,
    *,
    force: bool = False,
    option: str = "",
    make_folders: bool = False,
) -> Path:
    """Write one output atomically (see :class:`StagedWrites`)."""
    with StagedWrites(force=force) as stage:
        stage.write(path, writer, option=option, make_folders=make_folders)
    return path


def fallback_folders(path: Path) -> list[Path]:
    """Where :func:`save_with_fallback` tries next: the file's folder (a new name), the
    working folder, the temporary folder (duplicates removed, order kept)."""
    out: list[Path] = []
    for folder in (path.parent, Path.cwd(), Path(tempfile.gettempdir())):
        key = _resolve(folder)
        if all(_resolve(f) != key for f in out):
            out.append(folder)
    return out


def save_with_fallback(
    path: Path,
    writer: Writer,
    *,
    force: bool = False,
    option: str = "",
    warn: Callable[[str], None],
) -> Path:
    """Write ``path`` atomically; if that fails, write a new file in the first writable
    :func:`fallback_folders` folder and ``warn`` where it went. Returns the path written;
    raises :class:`OutputPathError` only when no folder at all could take the file."""
    try:
        return write_atomic(path, writer, force=force, option=option)
    except OutputPathError as exc:
        first = exc
    tried: list[str] = []
    for folder in fallback_folders(path):
        candidate = folder / f"{path.stem}-{secrets.token_hex(3)}{path.suffix}"
        tried.append(str(folder))
        try:
            write_atomic(candidate, writer, force=False, option=option)
        except OutputPathError:
            continue
        warn(f"warning: {first}; saved to {candidate} instead")
        return candidate
    raise OutputPathError(
        f"{first.reason}; no fallback folder could take it either (tried {', '.join(tried)})",
        path=path,
        option=option,
    )
