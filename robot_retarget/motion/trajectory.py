"""RobotTrajectory: joint angles over time for one robot, and its CSV / JSON / NPZ files.

Angles are radians in the robot config's joint order. Files:

- CSV: header ``time,<joint>,...`` then one row per frame (time in seconds, angles in radians).
  When known, ``root_x,root_y,root_z`` (m), ``root_qw,root_qx,root_qy,root_qz`` and
  ``frame_ms`` columns follow the joints. fps and t0 come from the time column.
- JSON: one object with ``joint_names``, ``fps``, ``t0``, ``q`` (list of rows) and, when
  known, ``root_pos``, ``root_quat``, ``frame_ms``.
- NPZ: arrays ``joint_names`` (str), ``q``, ``fps`` and, when known, ``root_pos``,
  ``root_quat``, ``t0``, ``frame_ms``.

Writers never replace an existing file unless ``overwrite=True``; NaN or infinite values, and a
``root_quat`` that is not a unit quaternion, are refused when writing and when reading.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import InvalidMotionError, MotionFormatError, OutputWriteError
from robot_retarget.npz_errors import npz_unreadable_reason

ROOT_POS_COLUMNS: tuple[str, ...] = ("root_x", "root_y", "root_z")
ROOT_QUAT_COLUMNS: tuple[str, ...] = ("root_qw", "root_qx", "root_qy", "root_qz")
FRAME_MS_COLUMN = "frame_ms"
_RESERVED = {"time", FRAME_MS_COLUMN, *ROOT_POS_COLUMNS, *ROOT_QUAT_COLUMNS}
FORMATS: tuple[str, ...] = (".csv", ".json", ".npz")
# How far a root_quat's norm may be from 1: a float32 or 4-decimal round trip stays well inside
# it; further off, the file's base orientation is not a rotation (or not w-x-y-z) and is refused.
QUAT_NORM_TOLERANCE = 1e-3


def _optional(value: npt.ArrayLike | None, shape: tuple[int, ...], name: str) -> FloatArray | None:
    if value is None:
        return None
    arr = np.array(value, dtype=np.float64)
    if arr.shape != shape:
        raise InvalidMotionError(f"{name} must have shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


def _format_of(p: Path) -> str:
    """The file's suffix, lower case, if it is a trajectory format this module writes."""
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise MotionFormatError(
            f"unsupported trajectory file type {p.suffix or '(none)'!r}; use one of "
            f"{', '.join(FORMATS)}",
            path=p,
        )
    return suffix


@dataclass(frozen=True, eq=False)
class RobotTrajectory:
    """Joint angles ``q`` (T, J) in radians at ``fps``; frame k is at ``t0 + k / fps`` s.

    Optional: ``root_pos`` (T, 3) metres, ``root_quat`` (T, 4) w-x-y-z, ``frame_ms`` (T,)
    (e.g. measured per-frame compute time).
    """

    joint_names: tuple[str, ...]
    q: FloatArray = field(repr=False)
    fps: float
    root_pos: FloatArray | None = field(default=None, repr=False)
    root_quat: FloatArray | None = field(default=None, repr=False)
    t0: float = 0.0
    frame_ms: FloatArray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.joint_names)
        q = np.array(self.q, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != len(names) or q.shape[0] == 0:
            raise InvalidMotionError(f"q must have shape (T>0, {len(names)}), got {q.shape}")
        if len(set(names)) != len(names) or any(not n for n in names):
            raise InvalidMotionError(f"joint names must be unique and non-empty: {list(names)}")
        if not (math.isfinite(self.fps) and self.fps > 0.0):
            raise InvalidMotionError(f"fps must be positive, got {self.fps}")
        if not math.isfinite(self.t0):
            raise InvalidMotionError(f"t0 must be finite, got {self.t0}")
        t = q.shape[0]
        q.setflags(write=False)
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "fps", float(self.fps))
        object.__setattr__(self, "t0", float(self.t0))
        object.__setattr__(self, "root_pos", _optional(self.root_pos, (t, 3), "root_pos"))
        object.__setattr__(self, "root_quat", _optional(self.root_quat, (t, 4), "root_quat"))
        object.__setattr__(self, "frame_ms", _optional(self.frame_ms, (t,), "frame_ms"))

    @property
    def num_frames(self) -> int:
        return int(self.q.shape[0])

    @property
    def duration_s(self) -> float:
        return self.num_frames / self.fps

    def times_s(self) -> FloatArray:
        """Time of each frame in seconds."""
        return np.asarray(self.t0 + np.arange(self.num_frames) / self.fps, dtype=np.float64)

    def check_values(self, path: str | Path | None = None) -> None:
        """Raise MotionFormatError naming the first NaN / infinite value or the first
        ``root_quat`` that is not a unit quaternion, if any."""
        self.check_finite(path)
        if self.root_quat is None:
            return
        off = np.abs(np.linalg.norm(self.root_quat, axis=1) - 1.0)
        bad = np.flatnonzero(off > QUAT_NORM_TOLERANCE)
        if bad.size:
            frame = int(bad[0])
            norm = float(np.linalg.norm(self.root_quat[frame]))
            raise MotionFormatError(
                f"root_quat at frame {frame} has norm {norm:.6g} ({bad.size} of "
                f"{self.num_frames} frames off 1 by more than {QUAT_NORM_TOLERANCE:g}); the base "
                "orientation must be a unit quaternion w-x-y-z (normalise it, or check the "
                "column order)",
                path=path,
            )

    def check_finite(self, path: str | Path | None = None) -> None:
        """Raise MotionFormatError naming the first NaN / infinite value, if any."""
        arrays = {"q": self.q, "root_pos": self.root_pos, "root_quat": self.root_quat}
        arrays["frame_ms"] = self.frame_ms
        for name, arr in arrays.items():
            if arr is None:
                continue
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                frame = int(bad[0][0])
                what = name
                if name == "q":
                    what = f"joint {self.joint_names[int(bad[0][1])]}"
                raise MotionFormatError(
                    f"{what} is {arr[tuple(bad[0])]} at frame {frame}; trajectories must be finite "
                    "(fix or cut the bad frames)",
                    path=path,
                )

    # --- files ---------------------------------------------------------------------------

    def write(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Write as CSV, JSON or NPZ, chosen by the file suffix."""
        p = Path(path)
        suffix = _format_of(p)
        if p.exists() and not overwrite:
            raise OutputWriteError(
                "the file already exists; pass overwrite=True (--force on the command line) to "
                "replace it",
                path=p,
            )
        self.check_values(p)
        if not p.parent.is_dir():
            raise OutputWriteError(f"no folder {p.parent} to write into; create it first", path=p)
        tmp = p.with_name(p.name + ".part")
        try:
            if suffix == ".csv":
                tmp.write_text(self._csv_text(p), encoding="utf-8")
            elif suffix == ".json":
                tmp.write_text(json.dumps(self._json_object(), indent=1) + "\n", encoding="utf-8")
            else:
                with tmp.open("wb") as fh:
                    np.savez(fh, **self._npz_arrays())  # type: ignore[arg-type]
            os.replace(tmp, p)
        except OSError as exc:  # a read-only folder, a full disk: nothing half-written stays
            tmp.unlink(missing_ok=True)
            raise OutputWriteError(f"cannot write the file ({exc.strerror})", path=p) from exc
        return p

    @classmethod
    def read(cls, path: str | Path) -> RobotTrajectory:
        """Read a CSV, JSON or NPZ trajectory (chosen by suffix)."""
        p = Path(path)
        if p.is_dir():
            raise MotionFormatError(
                "a folder, not a trajectory file: name one of the files in it (convert writes "
                "one per clip)",
                path=p,
            )
        if p.suffix.lower() == ".bvh":
            raise MotionFormatError(
                "a BVH motion clip, not a robot trajectory: convert it first (convert CLIP.bvh "
                "--out TRAJ.npz), then take TRAJ.npz (view shows the clip beside it with --clip "
                "CLIP.bvh)",
                path=p,
            )
        suffix = _format_of(p)
        try:
            if suffix == ".csv":
                traj = _read_csv(p)
            elif suffix == ".json":
                traj = _read_json(p)
            else:
                traj = _read_npz(p)
        except OSError as exc:
            raise MotionFormatError(
                f"cannot read the file: {exc.strerror or exc}", path=p
            ) from None
        traj.check_values(p)
        return traj

    def _csv_text(self, path: Path) -> str:
        clash = _RESERVED.intersection(self.joint_names)
        if clash:
            raise MotionFormatError(
                f"joint names {sorted(clash)} clash with reserved CSV columns; rename the joints "
                "or write JSON / NPZ",
                path=path,
            )
        header = ["time", *self.joint_names]
        cols = [self.times_s()[:, None], self.q]
        if self.root_pos is not None:
            header += ROOT_POS_COLUMNS
            cols.append(self.root_pos)
        if self.root_quat is not None:
            header += ROOT_QUAT_COLUMNS
            cols.append(self.root_quat)
        if self.frame_ms is not None:
            header.append(FRAME_MS_COLUMN)
            cols.append(self.frame_ms[:, None])
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(header)
        writer.writerows([repr(v) for v in row] for row in np.hstack(cols).tolist())
        return buf.getvalue()

    def _json_object(self) -> dict[str, Any]:
        obj: dict[str, Any] = {
            "joint_names": list(self.joint_names),
            "fps": self.fps,
            "t0": self.t0,
            "q": self.q.tolist(),
        }
        for key in ("root_pos", "root_quat", "frame_ms"):
            arr = getattr(self, key)
            if arr is not None:
                obj[key] = arr.tolist()
        return obj

    def _npz_arrays(self) -> dict[str, npt.NDArray[Any]]:
        arrays: dict[str, npt.NDArray[Any]] = {
            "joint_names": np.array(self.joint_names, dtype=str),
            "q": self.q,
            "fps": np.array(self.fps),
            "t0": np.array(self.t0),
        }
        for key in ("root_pos", "root_quat", "frame_ms"):
            arr = getattr(self, key)
            if arr is not None:
                arrays[key] = arr
        return arrays


def _build(path: Path, line: int | None = None, **kwargs: Any) -> RobotTrajectory:
    try:
        return RobotTrajectory(**kwargs)
    except (ValueError, TypeError) as exc:
        raise MotionFormatError(str(exc), path=path, line=line) from None


def _read_csv(path: Path) -> RobotTrajectory:
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"))))
    numbered = [(i + 1, r) for i, r in enumerate(rows) if r and any(c.strip() for c in r)]
    if not numbered:
        raise MotionFormatError(
            "empty file; expected a header 'time,<joint>,...'", path=path, line=1
        )
    header_line, header = numbered[0]
    header = [h.strip() for h in header]
    if header[0] != "time":
        raise MotionFormatError(
            f"the first column must be 'time', found {header[0]!r}; header is 'time,<joint>,...'",
            path=path,
            line=header_line,
        )
    extras = [h for h in header[1:] if h in _RESERVED]
    joints = [h for h in header[1:] if h not in _RESERVED]
    expected_tail = [
        *(ROOT_POS_COLUMNS if ROOT_POS_COLUMNS[0] in extras else ()),
        *(ROOT_QUAT_COLUMNS if ROOT_QUAT_COLUMNS[0] in extras else ()),
        *((FRAME_MS_COLUMN,) if FRAME_MS_COLUMN in extras else ()),
    ]
    if header[1 + len(joints) :] != expected_tail or not joints:
        raise MotionFormatError(
            "bad header: joints must come right after 'time', followed optionally by "
            f"{','.join(ROOT_POS_COLUMNS)}, {','.join(ROOT_QUAT_COLUMNS)} and {FRAME_MS_COLUMN}",
            path=path,
            line=header_line,
        )
    if len(numbered) < 2:
        raise MotionFormatError("no data rows after the header", path=path, line=header_line + 1)
    data = np.empty((len(numbered) - 1, len(header)))
    for k, (line, row) in enumerate(numbered[1:]):
        if len(row) != len(header):
            raise MotionFormatError(
                f"row has {len(row)} values but the header has {len(header)} columns",
                path=path,
                line=line,
            )
        try:
            data[k] = [float(v) for v in row]
        except ValueError:
            raise MotionFormatError(
                f"row has a value that is not a number: {row}", path=path, line=line
            ) from None
        if not np.all(np.isfinite(data[k])):
            raise MotionFormatError(
                "row contains NaN or infinity; trajectories must be finite", path=path, line=line
            )
    times = data[:, 0]
    if times.size < 2:
        raise MotionFormatError(
            "need at least two rows to know the frame rate", path=path, line=numbered[-1][0]
        )
    steps = np.diff(times)
    if np.any(steps <= 0.0):
        k = int(np.flatnonzero(steps <= 0.0)[0]) + 2
        raise MotionFormatError(
            "time must increase from row to row", path=path, line=numbered[k][0]
        )
    fps = (times.size - 1) / (times[-1] - times[0])
    j = 1 + len(joints)
    root_pos = root_quat = frame_ms = None
    if ROOT_POS_COLUMNS[0] in extras:
        root_pos, j = data[:, j : j + 3], j + 3
    if ROOT_QUAT_COLUMNS[0] in extras:
        root_quat, j = data[:, j : j + 4], j + 4
    if FRAME_MS_COLUMN in extras:
        frame_ms = data[:, j]
    return _build(
        path,
        header_line,
        joint_names=tuple(joints),
        q=data[:, 1 : 1 + len(joints)],
        fps=fps,
        root_pos=root_pos,
        root_quat=root_quat,
        t0=float(times[0]),
        frame_ms=frame_ms,
    )


def _read_json(path: Path) -> RobotTrajectory:
    try:
        obj = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise MotionFormatError(f"not valid JSON: {exc.msg}", path=path, line=exc.lineno) from None
    if not isinstance(obj, dict):
        raise MotionFormatError("expected a JSON object with joint_names, fps and q", path=path)
    missing = [k for k in ("joint_names", "fps", "q") if k not in obj]
    if missing:
        raise MotionFormatError(
            f"missing keys {missing}; a trajectory needs joint_names, fps, q", path=path
        )
    try:
        arrays = {
            k: np.array(obj[k], dtype=np.float64)
            for k in ("q", "root_pos", "root_quat", "frame_ms")
            if obj.get(k) is not None
        }
        fps = float(obj["fps"])
        t0 = float(obj.get("t0", 0.0))
    except (TypeError, ValueError) as exc:
        raise MotionFormatError(
            f"values are not numbers of the right shape: {exc}", path=path
        ) from None
    names = obj["joint_names"]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise MotionFormatError("joint_names must be a list of strings", path=path)
    for name, arr in arrays.items():
        if not np.all(np.isfinite(arr)):
            raise MotionFormatError(f"{name} contains NaN or infinity", path=path)
    return _build(path, None, joint_names=tuple(names), fps=fps, t0=t0, **arrays)


def _read_npz(path: Path) -> RobotTrajectory:
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
    except (zipfile.BadZipFile, ValueError, EOFError) as exc:
        raise MotionFormatError(npz_unreadable_reason(exc), path=path) from None
    missing = [k for k in ("joint_names", "q", "fps") if k not in data]
    if missing:
        raise MotionFormatError(
            f"missing arrays {missing}; a trajectory needs joint_names, q, fps", path=path
        )
    names = data["joint_names"]
    if names.dtype.kind not in "US" or names.ndim != 1:
        raise MotionFormatError("joint_names must be a 1-D string array", path=path)
    try:
        floats = {
            k: np.asarray(data[k], dtype=np.float64)
            for k in ("q", "root_pos", "root_quat", "frame_ms")
            if k in data
        }
        fps = float(data["fps"])
        t0 = float(data["t0"]) if "t0" in data else 0.0
    except (TypeError, ValueError) as exc:
        raise MotionFormatError(f"arrays have the wrong type or shape: {exc}", path=path) from None
    for name, arr in floats.items():
        if not np.all(np.isfinite(arr)):
            raise MotionFormatError(f"{name} contains NaN or infinity", path=path)
    return _build(path, None, joint_names=tuple(str(n) for n in names), fps=fps, t0=t0, **floats)
