"""BVH (Biovision Hierarchy) reading and writing, and the raw clip it describes.

A :class:`BvhClip` is the file as written: joint tree, OFFSETs and End Sites in file units,
per-joint channel lists and the (T, C) channel matrix (rotations in degrees). Mapping onto the
canonical human skeleton, unit detection and T-pose handling live elsewhere (canonicalize.py).

Conventions (those of every common exporter):

- rotation channels compose in listed order, R = R_c0 · R_c1 · R_c2 (intrinsic Euler);
- position channels give the joint's translation from its parent in the parent's frame and
  *replace* the matching OFFSET component (the root's OFFSET is usually zero anyway);
- joints are stored in file order, which is topological (parents first).

Every malformed input raises :class:`~robot_retarget.errors.MotionFormatError` with the file
path and the 1-based line number where the problem is.
"""

from __future__ import annotations

import codecs
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import MotionFormatError
from robot_retarget.geometry import euler
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.frame_rate import FPS_RANGE, plausible_fps
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

if TYPE_CHECKING:
    from robot_retarget.motion.human_motion import HumanMotion


POSITION_CHANNELS: tuple[str, ...] = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS: tuple[str, ...] = ("Xrotation", "Yrotation", "Zrotation")
_CHANNEL_BY_LOWER = {c.lower(): c for c in POSITION_CHANNELS + ROTATION_CHANNELS}

DEFAULT_ROOT_CHANNELS: tuple[str, ...] = (
    "Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation",
)  # fmt: skip
DEFAULT_JOINT_CHANNELS: tuple[str, ...] = ("Zrotation", "Yrotation", "Xrotation")


@dataclass(frozen=True, eq=False)
class BvhClip:
    """A BVH file as written. Lengths in file units, angles in degrees (as in the file).

    ``channels[j]`` lists joint j's channel names (canonical spelling, e.g. ``"Zrotation"``);
    its values are columns ``channel_start[j] : channel_start[j] + len(channels[j])`` of
    ``motion``. ``end_site_parents[e]`` is the joint that End Site e hangs from, at
    ``end_site_offsets[e]`` in that joint's frame.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: FloatArray = field(repr=False)
    channels: tuple[tuple[str, ...], ...] = field(repr=False)
    end_site_parents: tuple[int, ...] = field(repr=False)
    end_site_offsets: FloatArray = field(repr=False)
    frame_time_s: float
    motion: FloatArray = field(repr=False)
    path: str | None = None

    def __post_init__(self) -> None:
        n = len(self.names)
        offsets = np.array(self.offsets, dtype=np.float64).reshape(-1, 3)
        end_offsets = np.array(self.end_site_offsets, dtype=np.float64).reshape(-1, 3)
        motion = np.array(self.motion, dtype=np.float64)
        if len(self.parents) != n or offsets.shape[0] != n or len(self.channels) != n:
            raise ValueError(
                f"BvhClip sizes disagree: {n} names, {len(self.parents)} parents, "
                f"{offsets.shape[0]} offsets, {len(self.channels)} channel lists"
            )
        if len(self.end_site_parents) != end_offsets.shape[0]:
            raise ValueError("end_site_parents and end_site_offsets have different lengths")
        num_channels = sum(len(c) for c in self.channels)
        if motion.ndim != 2 or motion.shape[1] != num_channels:
            raise ValueError(
                f"motion must have shape (T, {num_channels}) for these channels, got {motion.shape}"
            )
        if not (math.isfinite(self.frame_time_s) and self.frame_time_s > 0.0):
            raise ValueError(f"frame_time_s must be positive, got {self.frame_time_s}")
        for a in (offsets, end_offsets, motion):
            a.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "end_site_offsets", end_offsets)
        object.__setattr__(self, "motion", motion)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "channels", tuple(tuple(c) for c in self.channels))
        object.__setattr__(self, "end_site_parents", tuple(int(p) for p in self.end_site_parents))

    # --- sizes ---------------------------------------------------------------------------

    @property
    def num_joints(self) -> int:
        return len(self.names)

    @property
    def num_frames(self) -> int:
        return int(self.motion.shape[0])

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time_s

    @property
    def duration_s(self) -> float:
        return self.num_frames * self.frame_time_s

    @cached_property
    def channel_start(self) -> tuple[int, ...]:
        """First column of each joint's channels in ``motion``."""
        starts = np.cumsum([0] + [len(c) for c in self.channels[:-1]])
        return tuple(int(s) for s in starts)

    @cached_property
    def skeleton(self) -> Skeleton:
        """The joint tree with OFFSETs, in file units."""
        return Skeleton(self.names, self.parents, self.offsets)

    def children(self, joint: int) -> tuple[int, ...]:
        return tuple(j for j, p in enumerate(self.parents) if p == joint)

    # --- frames --------------------------------------------------------------------------

    def frames(self, start: int = 0, stop: int | None = None) -> BvhClip:
        """The clip restricted to frames ``start:stop``."""
        motion = self.motion[start:stop]
        if motion.shape[0] == 0:
            raise ValueError(f"frames({start}, {stop}) selects no frame of {self.num_frames}")
        return BvhClip(
            self.names,
            self.parents,
            self.offsets,
            self.channels,
            self.end_site_parents,
            self.end_site_offsets,
            self.frame_time_s,
            motion,
            self.path,
        )

    # --- kinematics ----------------------------------------------------------------------

    def local_rotations(self) -> FloatArray:
        """Local joint rotations (T, J, 4) as unit quaternions w-x-y-z (identity if none)."""
        t = self.num_frames
        out = quat.identity((t, self.num_joints))
        # Group joints by rotation-channel layout so each group converts in one numpy call.
        groups: dict[tuple[str, ...], list[tuple[int, list[int]]]] = {}
        for j, chans in enumerate(self.channels):
            cols = [
                self.channel_start[j] + k for k, c in enumerate(chans) if c.endswith("rotation")
            ]
            if cols:
                order = tuple(self.channels[j][c - self.channel_start[j]][0] for c in cols)
                groups.setdefault(order, []).append((j, cols))
        for order, members in groups.items():
            joints = [j for j, _ in members]
            cols_arr = np.array([cols for _, cols in members])  # (G, K)
            angles = np.radians(self.motion[:, cols_arr])  # (T, G, K)
            out[:, joints] = _compose_rotations(angles, order)
        return out

    def local_translations(self) -> FloatArray:
        """Per-frame offsets (T, J, 3): OFFSET with position channels substituted."""
        trans = np.broadcast_to(self.offsets, (self.num_frames, self.num_joints, 3)).copy()
        for j, chans in enumerate(self.channels):
            for k, c in enumerate(chans):
                if c.endswith("position"):
                    trans[:, j, "XYZ".index(c[0])] = self.motion[:, self.channel_start[j] + k]
        return trans

    def global_transforms(self) -> tuple[FloatArray, FloatArray]:
        """Global joint positions (T, J, 3, file units) and rotations (T, J, 4) per frame."""
        trans = self.local_translations()
        return forward_kinematics(
            self.skeleton, self.local_rotations(), root_pos=trans[:, 0], offsets=trans
        )

    def global_positions(self) -> FloatArray:
        """Global joint positions (T, J, 3) in file units."""
        return self.global_transforms()[0]

    def end_site_positions(self) -> FloatArray:
        """Global End Site positions (T, E, 3) in file units."""
        pos, rot = self.global_transforms()
        parents = list(self.end_site_parents)
        return pos[:, parents] + quat.rotate(rot[:, parents], self.end_site_offsets)

    def rest_positions(self) -> FloatArray:
        """Joint positions (J, 3) in the rest pose (all channels zero except OFFSETs)."""
        return self.skeleton.rest_positions()

    def rest_end_site_positions(self) -> FloatArray:
        """End Site positions (E, 3) in the rest pose."""
        rest = self.rest_positions()
        return rest[list(self.end_site_parents)] + self.end_site_offsets


def _compose_rotations(angles_rad: FloatArray, axes: tuple[str, ...]) -> FloatArray:
    """R = R_axes[0](a0) · R_axes[1](a1) · … for any number of rotation channels."""
    order = "".join(axes).upper()
    if len(order) == 3 and order[0] != order[1] and order[1] != order[2]:
        return euler.from_euler(angles_rad, order)
    out = quat.identity(angles_rad.shape[:-1])
    for k, axis in enumerate(order):
        unit = np.zeros(3)
        unit["XYZ".index(axis)] = 1.0
        out = quat.mul(out, quat.from_axis_angle(unit, angles_rad[..., k]))
    return out


# --- reading ------------------------------------------------------------------------------


class _Tokens:
    """Whitespace-separated header tokens with their 1-based line numbers."""

    def __init__(self, lines: Sequence[str], path: str | None, end: tuple[str, int]) -> None:
        self.items: list[tuple[str, int]] = []
        self.path = path
        self.end_what, self.end_line = end
        for number, line in enumerate(lines, start=1):
            for tok in line.replace("{", " { ").replace("}", " } ").split():
                self.items.append((tok, number))
        self.pos = 0

    def error(self, message: str, line: int | None = None) -> MotionFormatError:
        return MotionFormatError(message, path=self.path, line=line)

    def peek(self) -> tuple[str, int] | None:
        return self.items[self.pos] if self.pos < len(self.items) else None

    def next(self, expected: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise self.error(f"missing {expected}: {self.end_what}", self.end_line)
        item = self.items[self.pos]
        self.pos += 1
        return item

    def rest_of_line(self, line: int) -> list[str]:
        """Consume the remaining tokens on ``line`` (stopping before a brace)."""
        out: list[str] = []
        while self.pos < len(self.items):
            tok, ln = self.items[self.pos]
            if ln != line or tok in "{}":
                break
            out.append(tok)
            self.pos += 1
        return out


class _HeaderBuilder:
    def __init__(self) -> None:
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[tuple[float, float, float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_parents: list[int] = []
        self.end_offsets: list[tuple[float, float, float]] = []


def _parse_offset(tokens: _Tokens) -> tuple[float, float, float]:
    tok, line = tokens.next("OFFSET")
    if tok.upper() != "OFFSET":
        raise tokens.error(
            f"expected OFFSET, found {tok!r}; every joint starts with OFFSET x y z", line
        )
    values = tokens.rest_of_line(line)
    if len(values) != 3:
        raise tokens.error(f"OFFSET needs 3 numbers on its line, found {len(values)}", line)
    try:
        x, y, z = (float(v) for v in values)
    except ValueError:
        raise tokens.error(f"OFFSET values {values} are not all numbers", line) from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise tokens.error(f"OFFSET values {values} must be finite", line)
    if max(abs(x), abs(y), abs(z)) > MAX_ABS_VALUE:
        raise tokens.error(
            f"OFFSET values {values} are beyond ±{MAX_ABS_VALUE:g}: no bone in any unit", line
        )
    return (x, y, z)


def _parse_channels(tokens: _Tokens) -> tuple[str, ...]:
    item = tokens.peek()
    if item is None or item[0].upper() != "CHANNELS":
        return ()  # a joint without CHANNELS is fixed (allowed)
    _, line = tokens.next("CHANNELS")
    values = tokens.rest_of_line(line)
    if not values:
        raise tokens.error("CHANNELS needs a count followed by that many channel names", line)
    try:
        count = int(values[0])
    except ValueError:
        raise tokens.error(f"CHANNELS count {values[0]!r} is not an integer", line) from None
    listed = values[1:]
    if count < 0 or count != len(listed):
        raise tokens.error(
            f"CHANNELS says {values[0]} channels but lists {len(listed)} ({' '.join(listed)}); "
            "make the count match the names",
            line,
        )
    out: list[str] = []
    for name in listed:
        canonical = _CHANNEL_BY_LOWER.get(name.lower())
        if canonical is None:
            allowed = ", ".join(POSITION_CHANNELS + ROTATION_CHANNELS)
            raise tokens.error(f"unknown channel {name!r}; channels must be one of {allowed}", line)
        if canonical in out:
            raise tokens.error(f"channel {canonical} is listed twice", line)
        out.append(canonical)
    return tuple(out)


def _expect_brace(tokens: _Tokens, brace: str, what: str) -> None:
    tok, line = tokens.next(f"'{brace}'")
    if tok != brace:
        raise tokens.error(f"missing '{brace}' {what} (found {tok!r})", line)


def _parse_joint(
    tokens: _Tokens, builder: _HeaderBuilder, parent: int, name: str, line: int, depth: int = 0
) -> None:
    if depth > MAX_DEPTH:
        raise tokens.error(
            f"joint {name!r} is nested {depth} joints deep; a skeleton is at most {MAX_DEPTH} "
            "(is a '}' missing above?)",
            line,
        )
    if name in builder.names:
        raise tokens.error(f"duplicate joint name {name!r}; joint names must be unique", line)
    index = len(builder.names)
    builder.names.append(name)
    builder.parents.append(parent)
    _expect_brace(tokens, "{", f"after joint {name!r}")
    builder.offsets.append(_parse_offset(tokens))
    builder.channels.append(_parse_channels(tokens))
    while True:
        tok, ln = tokens.next(f"'}}' closing joint {name!r}")
        key = tok.upper()
        if tok == "}":
            return
        if key == "JOINT":
            child = " ".join(tokens.rest_of_line(ln))
            if not child:
                raise tokens.error("JOINT needs a name on the same line", ln)
            _parse_joint(tokens, builder, index, child, ln, depth + 1)
        elif key == "END":
            site, _ = tokens.next("'Site'")
            if site.upper() != "SITE":
                raise tokens.error(f"expected 'End Site', found 'End {site}'", ln)
            _expect_brace(tokens, "{", "after End Site")
            builder.end_parents.append(index)
            builder.end_offsets.append(_parse_offset(tokens))
            _expect_brace(tokens, "}", "closing End Site")
        elif key in ("MOTION", "ROOT"):
            raise tokens.error(f"missing '}}' closing joint {name!r} before {tok}", ln)
        else:
            raise tokens.error(
                f"unexpected {tok!r} inside joint {name!r}; expected JOINT, End Site or '}}'", ln
            )


MAX_DEPTH = 200  # joints from the root: a hand's fingertip is about 30
# Any channel or offset: 10⁷ file units is 10 km even in millimetres, 10⁷ degrees 28 000 turns.
MAX_ABS_VALUE = 1e7
_FRAMES_RE = re.compile(r"^\s*frames\s*:?\s*(\S*)\s*$", re.IGNORECASE)
FRAME_TIME_RE = re.compile(r"^\s*frame\s+time\s*:?\s*(\S*)\s*$", re.IGNORECASE)


def parse_bvh(
    text: str, *, path: str | Path | None = None, max_frames: int | None = None
) -> BvhClip:
    """Parse BVH text. ``max_frames`` reads only the first frames (the rest is not checked)."""
    where = None if path is None else str(path)
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    lines = text.removeprefix("\ufeff").splitlines()  # handles LF, CRLF and CR
    motion_line = next((i for i, ln in enumerate(lines) if ln.strip().upper() == "MOTION"), None)
    header_lines = lines if motion_line is None else lines[:motion_line]
    end = (
        ("the file ends (truncated?)", len(lines) + 1)
        if motion_line is None
        else ("found MOTION", motion_line + 1)
    )
    tokens = _Tokens(header_lines, where, end)
    builder = _HeaderBuilder()
    first = tokens.peek()
    if first is None or first[0].upper() != "HIERARCHY":
        line = 1 if first is None else first[1]
        raise MotionFormatError(
            "not a BVH file: it must start with HIERARCHY", path=where, line=line
        )
    tokens.next("HIERARCHY")
    tok, line = tokens.next("ROOT")
    if tok.upper() != "ROOT":
        raise tokens.error(f"expected ROOT after HIERARCHY, found {tok!r}", line)
    name = " ".join(tokens.rest_of_line(line))
    if not name:
        raise tokens.error("ROOT needs a name on the same line", line)
    _parse_joint(tokens, builder, -1, name, line)
    extra = tokens.peek()
    if extra is not None:
        raise tokens.error(
            f"unexpected {extra[0]!r} after the root joint closed; only one ROOT is supported",
            extra[1],
        )
    if motion_line is None:
        raise MotionFormatError(
            "missing MOTION section after the hierarchy; the file is truncated or not BVH",
            path=where,
            line=len(lines) + 1,
        )
    num_channels = sum(len(c) for c in builder.channels)
    frames, frame_time, first_row = _parse_motion_header(lines, motion_line, where)
    wanted = frames if max_frames is None else min(frames, int(max_frames))
    motion = _parse_motion_rows(lines, first_row, frames, wanted, num_channels, where)
    return BvhClip(
        tuple(builder.names),
        tuple(builder.parents),
        np.array(builder.offsets, dtype=np.float64),
        tuple(builder.channels),
        tuple(builder.end_parents),
        np.array(builder.end_offsets, dtype=np.float64).reshape(-1, 3),
        frame_time,
        motion,
        where,
    )


def _next_content_line(lines: Sequence[str], start: int) -> int:
    i = start
    while i < len(lines) and not lines[i].strip():
        i += 1
    return i


def _parse_motion_header(
    lines: Sequence[str], motion_line: int, where: str | None
) -> tuple[int, float, int]:
    """(Frames, Frame Time, index of the first motion row) from the lines after MOTION."""
    i = _next_content_line(lines, motion_line + 1)
    m = _FRAMES_RE.match(lines[i]) if i < len(lines) else None
    if m is None:
        raise MotionFormatError(
            "expected 'Frames: N' after MOTION", path=where, line=min(i, len(lines)) + 1
        )
    try:
        frames = int(m.group(1))
    except ValueError:
        raise MotionFormatError(
            f"Frames value {m.group(1)!r} is not an integer", path=where, line=i + 1
        ) from None
    if frames <= 0:
        raise MotionFormatError(
            f"Frames is {frames}: a BVH clip needs at least one frame", path=where, line=i + 1
        )
    j = _next_content_line(lines, i + 1)
    m = FRAME_TIME_RE.match(lines[j]) if j < len(lines) else None
    if m is None:
        raise MotionFormatError(
            "expected 'Frame Time: seconds' after Frames", path=where, line=min(j, len(lines)) + 1
        )
    try:
        frame_time = float(m.group(1))
    except ValueError:
        raise MotionFormatError(
            f"Frame Time {m.group(1)!r} is not a number", path=where, line=j + 1
        ) from None
    if not (math.isfinite(frame_time) and frame_time > 0.0):
        raise MotionFormatError(
            f"Frame Time is {m.group(1)}; it must be a positive number of seconds "
            "(e.g. 0.0083333 for 120 fps)",
            path=where,
            line=j + 1,
        )
    if not plausible_fps(1.0 / frame_time):
        raise MotionFormatError(
            f"Frame Time is {m.group(1)} s, {1.0 / frame_time:.3g} frames per second; motion "
            f"is recorded at {FPS_RANGE} (e.g. 0.0083333 for 120 fps): is the line in another "
            "unit?",
            path=where,
            line=j + 1,
        )
    return frames, frame_time, j + 1


def _parse_motion_rows(
    lines: Sequence[str],
    first_row: int,
    frames: int,
    wanted: int,
    num_channels: int,
    where: str | None,
) -> FloatArray:
    row_lines: list[int] = []
    rows: list[list[str]] = []
    i = first_row
    n = len(lines)
    while i < n and len(rows) < wanted:
        tokens = lines[i].split()
        if tokens:
            rows.append(tokens)
            row_lines.append(i + 1)
        i += 1
    # Rows past the ones wanted are counted too: a truncated file is refused whatever
    # --max-frames reads of it, as it is without.
    have = len(rows) + (sum(1 for k in range(i, n) if lines[k].strip()) if wanted < frames else 0)
    if have < frames:
        raise MotionFormatError(
            f"Frames says {frames} but the file has only {have} motion "
            f"row{'' if have == 1 else 's'}; the file is truncated (re-export it, or fix the "
            "Frames count)",
            path=where,
            line=n + 1,
        )
    if wanted == frames:
        trailing = next((k for k in range(i, n) if lines[k].strip()), None)
        if trailing is not None:
            raise MotionFormatError(
                f"more motion rows than Frames ({frames}); fix the Frames count",
                path=where,
                line=trailing + 1,
            )
    counts = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(counts != num_channels)
    if bad.size:
        k = int(bad[0])
        raise MotionFormatError(
            f"motion row {k + 1} has {counts[k]} values but the hierarchy declares "
            f"{num_channels} channels",
            path=where,
            line=row_lines[k],
        )
    flat = [tok for r in rows for tok in r]
    try:
        values = np.array(flat, dtype=np.float64)
    except ValueError:
        values = _locate_bad_number(rows, row_lines, where)
    motion = values.reshape(len(rows), num_channels)
    finite = np.isfinite(motion)
    if not finite.all():
        k = int(np.flatnonzero(~finite.all(axis=1))[0])
        col = int(np.flatnonzero(~finite[k])[0])
        raise MotionFormatError(
            f"motion row {k + 1}, value {col + 1} is {rows[k][col]}; NaN and infinity are not "
            "allowed (repair or cut the bad frames)",
            path=where,
            line=row_lines[k],
        )
    huge = np.abs(motion) > MAX_ABS_VALUE
    if huge.any():
        k = int(np.flatnonzero(huge.any(axis=1))[0])
        col = int(np.flatnonzero(huge[k])[0])
        raise MotionFormatError(
            f"motion row {k + 1}, value {col + 1} is {rows[k][col]}, beyond ±{MAX_ABS_VALUE:g}: "
            "no joint angle or position (repair or cut the bad frames)",
            path=where,
            line=row_lines[k],
        )
    return motion


def _locate_bad_number(
    rows: Sequence[Sequence[str]], row_lines: Sequence[int], where: str | None
) -> FloatArray:
    # Slow path, only reached when numpy refused a token: find it to name the line.
    for k, row in enumerate(rows):
        for col, tok in enumerate(row):
            try:
                float(tok)
            except ValueError:
                raise MotionFormatError(
                    f"motion row {k + 1}, value {col + 1} ({tok!r}) is not a number",
                    path=where,
                    line=row_lines[k],
                ) from None
    raise MotionFormatError("motion data contains a value that is not a number", path=where)


def read_bvh(path: str | Path, *, max_frames: int | None = None) -> BvhClip:
    """Read a BVH file (any channel order, CRLF or LF, tabs or spaces)."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise MotionFormatError(f"cannot read the file: {exc.strerror or exc}", path=p) from None
    if not raw.strip():
        raise MotionFormatError(
            f"the file is empty ({len(raw)} bytes): a BVH file starts with HIERARCHY", path=p
        )
    return parse_bvh(decode_bvh_bytes(raw), path=p, max_frames=max_frames)


def decode_bvh_bytes(raw: bytes) -> str:
    """A BVH file's text: UTF-8 (with or without the byte-order mark Windows editors write),
    UTF-16 with its mark, else Latin-1 (old exporters' joint names)."""
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        try:
            return raw.decode("utf-16")
        except UnicodeDecodeError:
            pass
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


# --- writing ------------------------------------------------------------------------------


def format_bvh(clip: BvhClip, *, digits: int = 10) -> str:
    """BVH text for a clip; ``digits`` significant digits per value (10 keeps 1e-9 precision)."""
    out: list[str] = ["HIERARCHY"]
    children: list[list[int]] = [[] for _ in clip.names]
    for j, p in enumerate(clip.parents):
        if p >= 0:
            children[p].append(j)
    ends: list[list[int]] = [[] for _ in clip.names]
    for e, p in enumerate(clip.end_site_parents):
        ends[p].append(e)

    def num(v: float) -> str:
        return f"{v:.{digits}g}"

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        out.append(f"{pad}{'ROOT' if clip.parents[j] < 0 else 'JOINT'} {clip.names[j]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {' '.join(num(v) for v in clip.offsets[j])}")
        if clip.channels[j]:
            out.append(f"{pad}\tCHANNELS {len(clip.channels[j])} {' '.join(clip.channels[j])}")
        for c in children[j]:
            emit(c, depth + 1)
        for e in ends[j]:
            out.append(f"{pad}\tEnd Site")
            out.append(f"{pad}\t{{")
            out.append(f"{pad}\t\tOFFSET {' '.join(num(v) for v in clip.end_site_offsets[e])}")
            out.append(f"{pad}\t}}")
        out.append(f"{pad}}}")

    emit(0, 0)
    out.append("MOTION")
    out.append(f"Frames: {clip.num_frames}")
    out.append(f"Frame Time: {clip.frame_time_s!r}")  # shortest exact form: fps survives
    fmt = " ".join([f"%.{digits}g"] * clip.motion.shape[1])
    out.extend(fmt % tuple(row) for row in clip.motion.tolist())
    return "\n".join(out) + "\n"


def write_bvh(
    path: str | Path,
    data: BvhClip | HumanMotion,
    *,
    overwrite: bool = False,
    root_channels: Sequence[str] = DEFAULT_ROOT_CHANNELS,
    joint_channels: Sequence[str] = DEFAULT_JOINT_CHANNELS,
    unit: str = "m",
    digits: int = 10,
) -> Path:
    """Write a BvhClip, or a HumanMotion on the canonical skeleton, to ``path``.

    For a HumanMotion, ``root_channels`` / ``joint_channels`` choose the channel order and
    ``unit`` the length unit of the file (see robot_retarget.motion.units). A BvhClip is written
    with its own channels and units. Refuses to replace an existing file unless ``overwrite``.
    """
    p = Path(path)
    if p.exists() and not overwrite:
        raise MotionFormatError(
            "the file already exists; pass overwrite=True (or choose another name) to replace it",
            path=p,
        )
    clip = (
        data
        if isinstance(data, BvhClip)
        else data.to_bvh_clip(root_channels=root_channels, joint_channels=joint_channels, unit=unit)
    )
    text = format_bvh(clip, digits=digits)
    tmp = p.with_name(p.name + ".part")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, p)
    return p
