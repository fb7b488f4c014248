"""The live-stream wire format: canonical-joint frames over UDP, as JSON or compact binary.

One datagram = one frame. Joints are the 22 canonical joints in canonical order
(robot_retarget.skeleton.canonical: Hips, Spine, Spine1, Spine2, Neck, Head, LeftShoulder,
LeftArm, LeftForeArm, LeftHand, RightShoulder, RightArm, RightForeArm, RightHand, LeftUpLeg,
LeftLeg, LeftFoot, LeftToeBase, RightUpLeg, RightLeg, RightFoot, RightToeBase). Coordinates:
metres, Y up, the performer facing +Z in the T-pose rest (BVH convention).

JSON (UTF-8 object, at most MAX_JSON_BYTES)::

    {"v": 1, "seq": 42, "t": 12.345, "kind": "positions",
     "joints": [[x, y, z], ... 22 rows],               # global positions (m)
     "token": "secret"}                                # only when the receiver wants one

    {"v": 1, "seq": 43, "t": 12.355, "kind": "rotations",
     "quats": [[w, x, y, z], ... 22 rows],             # local rotations (unit quaternions)
     "root": [x, y, z]}                                # Hips position (m)

Binary (little-endian, at most MAX_BINARY_BYTES)::

    offset size  field
    0      4     magic b"RRM1"
    4      1     version (1)
    5      1     kind: 1 = positions, 2 = rotations
    6      2     token length L (uint16; 0 = no token)
    8      4     seq (uint32)
    12     8     t (float64, seconds)
    20     L     token (UTF-8)
    20+L   ...   float32 values: positions 22×3 (x, y, z per joint);
                 rotations 3 (root x, y, z) then 22×4 (w, x, y, z per joint)

``seq`` must increase by at least one per frame and ``t`` must increase (seconds, any origin);
``seq`` 0 starts a new stream (a restarted sender may reset its clock). The receiver drops
duplicates, out-of-order, oversized, malformed and non-finite packets, and packets without the
expected token, and counts them. :func:`encode_json` / :func:`encode_binary` build packets
(senders, tests).
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import SourceError
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS

WIRE_VERSION = 1
MAGIC = b"RRM1"
MAX_JSON_BYTES = 16384
MAX_BINARY_BYTES = 4096
KIND_POSITIONS = "positions"
KIND_ROTATIONS = "rotations"
_KIND_CODES = {KIND_POSITIONS: 1, KIND_ROTATIONS: 2}
_KIND_NAMES = {v: k for k, v in _KIND_CODES.items()}
_HEADER = struct.Struct("<4sBBHId")
_J = len(CANONICAL_JOINTS)
_VALUES = {KIND_POSITIONS: _J * 3, KIND_ROTATIONS: 3 + _J * 4}


class WireError(SourceError):
    """A packet that breaks the wire format; ``reason`` is a SourceStats drop reason.

    Receivers count these (they never reach the control loop)."""

    def __init__(self, message: str, *, reason: str = "malformed") -> None:
        self.reason = reason
        super().__init__(message)


@dataclass(frozen=True)
class WirePacket:
    """A decoded packet. ``values``: positions (22, 3) or rotations (22, 4) with ``root`` (3,)."""

    kind: str
    seq: int
    t_s: float
    values: FloatArray
    root: FloatArray | None
    token: str


MAX_ABS_VALUE = 1e4  # metres (positions, the root); larger is no performer: a sender bug


def _finite(a: FloatArray) -> FloatArray:
    if not np.isfinite(a).all():
        raise WireError("packet contains NaN or infinite values", reason="nan")
    if (np.abs(a) > MAX_ABS_VALUE).any():
        raise WireError(
            f"a value of {float(np.abs(a).max()):.3g} (positions are metres; at most "
            f"{MAX_ABS_VALUE:g})"
        )
    return a


def seconds(value: object) -> float:
    """A packet's ``t``: a finite number of seconds (WireError otherwise)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise WireError("'t' must be a number (seconds)")
    try:
        t_s = float(value)
    except OverflowError:  # an integer too large for a float
        raise WireError("timestamp is not finite", reason="nan") from None
    if not math.isfinite(t_s):
        raise WireError("timestamp is not finite", reason="nan")
    return t_s


def json_object(data: bytes, what: str) -> dict[str, Any]:
    """A datagram's UTF-8 JSON object (WireError otherwise)."""
    try:
        # NaN/Infinity literals parse to floats and are caught by the finite checks.
        obj = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise WireError("not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise WireError(f"not a JSON document ({exc.msg} at column {exc.colno})") from None
    except RecursionError:
        raise WireError("JSON nested too deeply") from None
    except ValueError:  # json refuses integers of more than 4300 digits
        raise WireError("a number with thousands of digits") from None
    if not isinstance(obj, dict):
        raise WireError(f"{what} must be a JSON object")
    return obj


def decode(data: bytes) -> WirePacket:
    """JSON or binary (by the first bytes) → WirePacket; raises WireError with the reason."""
    if data[:4] == MAGIC:
        return decode_binary(data)
    return decode_json(data)


def decode_binary(data: bytes) -> WirePacket:
    if len(data) > MAX_BINARY_BYTES:
        raise WireError(f"binary packet of {len(data)} bytes", reason="oversized")
    if len(data) < _HEADER.size:
        raise WireError("binary packet shorter than its header")
    magic, version, kind_code, token_len, seq, t_s = _HEADER.unpack_from(data)
    if magic != MAGIC or version != WIRE_VERSION:
        raise WireError(f"unknown magic/version {magic!r}/{version}")
    kind = _KIND_NAMES.get(kind_code)
    if kind is None:
        raise WireError(f"unknown kind code {kind_code}")
    count = _VALUES[kind]
    start = _HEADER.size + token_len
    if len(data) != start + 4 * count:
        raise WireError(f"binary {kind} packet must be {start + 4 * count} bytes, got {len(data)}")
    try:
        token = data[_HEADER.size : start].decode("utf-8")
    except UnicodeDecodeError:
        raise WireError("token is not UTF-8") from None
    if not math.isfinite(t_s):
        raise WireError("timestamp is not finite", reason="nan")
    # Checked before the cast: float32 → float64 is exact, but a signalling NaN would make numpy
    # warn "invalid value in cast" from the receiver thread (an errstate guard costs 3 µs).
    raw = _finite(np.frombuffer(data, dtype="<f4", count=count, offset=start))
    return _packet(kind, int(seq), float(t_s), raw.astype(np.float64), token)


MIN_BONE_M = 0.005
"""A bone shorter than this (5 mm) is no body's: a tracker that lost the person often sends
every joint at one point (zeros), which solves to a straight-legged pose at full speed."""
_PARENTS = np.asarray(CANONICAL_PARENTS[1:])


def check_body(positions: FloatArray) -> FloatArray:
    """``positions`` (22, 3) if at least half of the canonical bones are longer than
    :data:`MIN_BONE_M`; else WireError (reason ``degenerate``): joints collapsed onto a point,
    not a pose."""
    bones = np.linalg.norm(positions[1:] - positions[_PARENTS], axis=1)
    short = int(np.count_nonzero(bones < MIN_BONE_M))
    if 2 * short > len(bones):
        raise WireError(
            f"{short} of {len(bones)} bones shorter than {MIN_BONE_M * 1e3:.0f} mm: the joints "
            "collapsed onto a point (a tracker that lost the person?), not a pose",
            reason="degenerate",
        )
    return positions


def _packet(kind: str, seq: int, t_s: float, values: FloatArray, token: str) -> WirePacket:
    if kind == KIND_POSITIONS:
        return WirePacket(kind, seq, t_s, check_body(values.reshape(_J, 3)), None, token)
    return WirePacket(kind, seq, t_s, values[3:].reshape(_J, 4), values[:3].copy(), token)


def _array(obj: dict[str, Any], key: str, shape: tuple[int, ...]) -> FloatArray:
    value = obj.get(key)
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise WireError(f"'{key}' is not a numeric array") from None
    if a.shape != shape:
        raise WireError(f"'{key}' must have shape {shape}, got {a.shape}")
    return _finite(a)


def decode_json(data: bytes) -> WirePacket:
    if len(data) > MAX_JSON_BYTES:
        raise WireError(f"JSON packet of {len(data)} bytes", reason="oversized")
    obj = json_object(data, "JSON packet")
    if obj.get("v") != WIRE_VERSION:
        raise WireError(f"unsupported version {obj.get('v')!r}; expected {WIRE_VERSION}")
    kind = obj.get("kind")
    seq = obj.get("seq")
    t_s = obj.get("t")
    token = obj.get("token", "")
    if not isinstance(kind, str) or kind not in _KIND_CODES:
        raise WireError(f"unknown kind {kind!r}; expected positions or rotations")
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise WireError("'seq' must be a non-negative integer")
    t = seconds(t_s)
    if not isinstance(token, str):
        raise WireError("'token' must be a string")
    if kind == KIND_POSITIONS:
        values = check_body(_array(obj, "joints", (_J, 3)))
        return WirePacket(kind, seq, t, values, None, token)
    quats = _array(obj, "quats", (_J, 4))
    root = _array(obj, "root", (3,))
    return WirePacket(kind, seq, t, quats, root, token)


def encode_json(
    kind: str,
    seq: int,
    t_s: float,
    values: npt.ArrayLike,
    root: npt.ArrayLike | None = None,
    token: str = "",
) -> bytes:
    """A JSON packet (see the module docstring)."""
    v = np.asarray(values, dtype=np.float64)
    obj: dict[str, Any] = {"v": WIRE_VERSION, "seq": int(seq), "t": float(t_s), "kind": kind}
    if kind == KIND_POSITIONS:
        obj["joints"] = v.tolist()
    elif kind == KIND_ROTATIONS:
        obj["quats"] = v.tolist()
        obj["root"] = np.asarray(root, dtype=np.float64).tolist()
    else:
        raise ValueError(f"kind must be {KIND_POSITIONS!r} or {KIND_ROTATIONS!r}, got {kind!r}")
    if token:
        obj["token"] = token
    return json.dumps(obj, separators=(",", ":")).encode("utf-8")


def encode_binary(
    kind: str,
    seq: int,
    t_s: float,
    values: npt.ArrayLike,
    root: npt.ArrayLike | None = None,
    token: str = "",
) -> bytes:
    """A binary packet (see the module docstring)."""
    if kind not in _KIND_CODES:
        raise ValueError(f"kind must be {KIND_POSITIONS!r} or {KIND_ROTATIONS!r}, got {kind!r}")
    tok = token.encode("utf-8")
    v = np.asarray(values, dtype=np.float64).ravel()
    if kind == KIND_ROTATIONS:
        v = np.concatenate([np.asarray(root, dtype=np.float64).ravel(), v])
    if v.size != _VALUES[kind]:
        raise ValueError(f"{kind} packets carry {_VALUES[kind]} values, got {v.size}")
    head = _HEADER.pack(MAGIC, WIRE_VERSION, _KIND_CODES[kind], len(tok), seq & 0xFFFFFFFF, t_s)
    return head + tok + v.astype("<f4").tobytes()
