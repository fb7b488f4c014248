"""The live keypoint wire format: one JSON datagram per camera frame, COCO-17 people.

UTF-8 JSON object, at most MAX_JSON_BYTES (a frame with 8 people fits easily)::

    {"v": 1, "seq": 42, "t": 12.345, "kind": "coco17",
     "people": [{"keypoints": [[x, y, score], ... 17]}, ...],   # pixels, COCO-17 order
     "image_size": [1280, 720],                                  # optional: width, height
     "token": "secret"}                                          # only when the receiver wants one

``image_size`` (optional) is the camera image's width and height in pixels: its centre is the
camera's principal point, which the image's planes use (otherwise they assume the camera points
at the performer's mean hip position; see robot_retarget.keypoints.online_reprojection).

A person's points may also be 17 [x, y] pairs with ``keypoint_scores`` (MMPose) or 51 flat
values (robot_retarget.sources.keypoints.coco_jsonl). ``people`` may be empty (nobody in view).
``seq`` and ``t`` follow the 3D stream's rules (robot_retarget.sources.wire: both increase;
``seq`` 0 starts a new stream). Scores below the receiver's threshold mark a point missing.
:func:`encode_keypoints` builds a packet (senders, tests).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robot_retarget.keypoints.sequence import check_image_size
from robot_retarget.sources.keypoints.coco_jsonl import CocoPersonError, parse_coco_person
from robot_retarget.sources.keypoints.frames import Person
from robot_retarget.sources.wire import WIRE_VERSION, WireError, json_object, seconds

KIND_COCO17 = "coco17"
MAX_JSON_BYTES = 32768


@dataclass(frozen=True)
class KeypointPacket:
    seq: int
    t_s: float
    people: list[Person]
    token: str
    image_size: tuple[float, float] | None = None


def decode_keypoints(data: bytes, min_confidence: float) -> KeypointPacket:
    """A datagram → KeypointPacket; raises WireError (with a SourceStats drop reason)."""
    if len(data) > MAX_JSON_BYTES:
        raise WireError(f"keypoint packet of {len(data)} bytes", reason="oversized")
    obj = json_object(data, "keypoint packet")
    if obj.get("v") != WIRE_VERSION or obj.get("kind") != KIND_COCO17:
        raise WireError(f"expected v {WIRE_VERSION}, kind {KIND_COCO17!r}")
    seq, t_s, token = obj.get("seq"), obj.get("t"), obj.get("token", "")
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise WireError("'seq' must be a non-negative integer")
    t = seconds(t_s)
    if not isinstance(token, str):
        raise WireError("'token' must be a string")
    people_obj = obj.get("people")
    if not isinstance(people_obj, list):
        raise WireError("'people' must be a list")
    people = []
    for person in people_obj:
        try:
            xy, conf, valid = parse_coco_person(person, min_confidence)
        except CocoPersonError as exc:
            raise WireError(f"person: {exc}") from None
        # A point sent with a score but no finite position is the sender's fault, not a point
        # it did not see (score 0, or a NaN score): the packet is dropped as "nan", not taken
        # as the person out of view.
        broken = ~np.isfinite(xy).all(axis=1) & (conf > 0.0)
        if broken.any():
            raise WireError(
                f"keypoint {int(np.flatnonzero(broken)[0])} has a score but a NaN or infinite "
                "position (send a point not seen with score 0)",
                reason="nan",
            )
        people.append((xy, conf, valid))
    return KeypointPacket(seq, t, people, token, _image_size(obj.get("image_size")))


def _image_size(value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    ok = isinstance(value, list) and len(value) == 2
    if ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        try:
            return check_image_size((value[0], value[1]))
        except (ValueError, OverflowError):
            pass
    raise WireError("'image_size' must be [width, height], two positive pixel counts")


def encode_keypoints(
    seq: int,
    t_s: float,
    people: list[npt.ArrayLike],
    token: str = "",
    image_size: tuple[float, float] | None = None,
) -> bytes:
    """A packet: ``people`` as (17, 3) arrays of x, y, score (NaN coordinates → score 0)."""
    rows = []
    for p in people:
        a = np.array(p, dtype=np.float64).reshape(17, 3)
        missing = ~np.isfinite(a).all(axis=1)
        a[missing] = 0.0
        rows.append({"keypoints": a.tolist()})
    obj: dict[str, Any] = {
        "v": WIRE_VERSION,
        "seq": int(seq),
        "t": float(t_s),
        "kind": KIND_COCO17,
        "people": rows,
    }
    if image_size is not None:
        obj["image_size"] = [float(image_size[0]), float(image_size[1])]
    if token:
        obj["token"] = token
    return json.dumps(obj, separators=(",", ":")).encode("utf-8")
