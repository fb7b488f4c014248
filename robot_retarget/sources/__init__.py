"""Motion sources: replayed clips and live streams, all delivering canonical-skeleton frames.

``open_source(spec)`` understands:

- ``replay:CLIP.bvh`` — a clip played in real time (``loop`` / ``speed`` options);
- ``udp://HOST:PORT`` — canonical joint positions or rotations, JSON or binary
  (wire format: :mod:`robot_retarget.sources.wire`);
- ``tcp-bvh://HOST:PORT`` — a BVH stream from mocap software (:mod:`.tcp_bvh`);
- ``udp-keypoints://HOST:PORT`` — COCO-17 2D keypoints from a camera pose estimator, lifted by
  the keypoint model (:mod:`.keypoints.udp_keypoints`).

Network sources use 127.0.0.1 unless ``allow_remote`` is given.
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlsplit

from robot_retarget.errors import SourceError
from robot_retarget.sources.base import MotionSource, SourceFrame, SourceStats
from robot_retarget.sources.replay import ReplaySource
from robot_retarget.sources.udp import DEFAULT_PORT, UdpSource

__all__ = [
    "MotionSource",
    "ReplaySource",
    "SourceFrame",
    "SourceStats",
    "UdpSource",
    "open_source",
]

SOURCE_FORMS = (
    "replay:CLIP.bvh, udp://127.0.0.1:9750, tcp-bvh://127.0.0.1:PORT or "
    "udp-keypoints://127.0.0.1:9751"
)


def _host_port(spec: str, default_port: int | None) -> tuple[str, int]:
    parts = urlsplit(spec)
    try:
        port = parts.port
    except ValueError:
        raise SourceError(f"bad port in source {spec!r}; use e.g. {SOURCE_FORMS}") from None
    host = parts.hostname or "127.0.0.1"
    if port is None:
        if default_port is None:
            raise SourceError(f"source {spec!r} needs a port, e.g. tcp-bvh://127.0.0.1:7001")
        port = default_port
    return host, port


def open_source(
    spec: str,
    *,
    loop: bool = False,
    speed: float = 1.0,
    token: str = "",
    allow_remote: bool = False,
    max_frames: int | None = None,
    keypoint_model: str | None = None,
    clean_positions: bool = True,
    image_planes: bool = True,
    image_size: tuple[float, float] | None = None,
) -> MotionSource:
    """A (not yet started) source for ``spec``; raises SourceError for anything unusable.
    ``clean_positions=False``: a UDP source solves position packets as sent (no frozen-joint,
    limb-swap or jitter cleanup, :mod:`robot_retarget.sources.position_cleanup`).
    ``image_planes=False``: a keypoint source keeps the keypoint model's answer as it is
    (:mod:`robot_retarget.keypoints.online_reprojection`); ``image_size`` (width, height px)
    puts its camera's principal point at the image centre."""
    if spec.startswith("replay:"):
        from robot_retarget.errors import MotionFormatError
        from robot_retarget.motion.human_motion import load_motion

        text = spec[len("replay:") :]
        if not text.strip():  # Path("") is ".", a folder: say what is missing instead
            raise SourceError("replay: names no clip; give replay:PATH/TO/CLIP.bvh")
        path = Path(text)
        if path.is_dir():
            raise SourceError(
                f"replay clip {path} is a folder; replay takes one clip: give "
                "replay:PATH/TO/CLIP.bvh"
            )
        if not path.is_file():
            raise SourceError(f"replay clip {path} does not exist; give replay:PATH/TO/CLIP.bvh")
        try:
            motion = load_motion(path, max_frames=max_frames)
        except MotionFormatError as exc:
            raise SourceError(f"cannot replay {path}: {exc}") from exc
        return ReplaySource(motion, loop=loop, speed=speed)
    if spec.startswith("udp://"):
        host, port = _host_port(spec, DEFAULT_PORT)
        return UdpSource(
            host, port, token=token, allow_remote=allow_remote, clean_positions=clean_positions
        )
    if spec.startswith("tcp-bvh://"):
        from robot_retarget.sources.tcp_bvh import TcpBvhSource

        host, port = _host_port(spec, None)
        return TcpBvhSource(host, port, allow_remote=allow_remote)
    if spec.startswith("udp-keypoints://"):
        from robot_retarget.runtime.agnostic2d import load_keypoint_model
        from robot_retarget.sources.keypoints.udp_keypoints import (
            DEFAULT_KEYPOINT_PORT,
            UdpKeypointSource,
        )
        from robot_retarget.sources.udp_datagram import check_bind_address

        host, port = _host_port(spec, DEFAULT_KEYPOINT_PORT)
        check_bind_address(host, allow_remote, "UDP bind")  # before loading anything
        model = load_keypoint_model(keypoint_model)
        return UdpKeypointSource(
            model,
            host,
            port,
            token=token,
            allow_remote=allow_remote,
            image_planes=image_planes,
            image_size=image_size,
        )
    raise SourceError(f"unknown source {spec!r}; use {SOURCE_FORMS}")
