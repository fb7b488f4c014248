"""UdpKeypointSource: live COCO-17 keypoints over UDP, lifted to canonical frames by the
keypoint model (wire format: robot_retarget.sources.keypoints.wire).

The same conventions as the 3D UdpSource (robot_retarget.sources.udp): binds 127.0.0.1
unless ``allow_remote``; a ``token``, when set, must be in every packet; sequence numbers and
timestamps checked by SequenceFilter; a receiver thread decodes into a bounded queue and
nothing a sender does can raise in, or stall, the control loop. Each accepted packet's people
go through the person rule (robot_retarget.sources.keypoints.person_choice), the followed
person's points through the glitch gate (robot_retarget.keypoints.glitch_gate) and the causal
keypoint model (Agnostic2DStep) and, unless
``image_planes=False``, the image's planes with the camera fitted on the frames so far
(robot_retarget.keypoints.online_reprojection); the frame delivered is the model's 22 canonical
rotations on the reference skeleton, the root held at its standing height
(robot_retarget.keypoints.lift). A sender restart (SequenceFilter's rule) starts all of that
over. A packet in which fewer than 6 of the 12 body points are seen
(nobody followed in view) delivers no frame (counted as ``no_person``): the control loop holds,
then goes to the safe pose, as when a sender falls silent.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.keypoints.coco17 import BODY_JOINTS, NUM_KEYPOINTS
from robot_retarget.keypoints.glitch_gate import KeypointGate
from robot_retarget.keypoints.lift import MIN_BODY_POINTS, standing_root
from robot_retarget.keypoints.online_reprojection import MIN_SECONDS, OnlineReprojection
from robot_retarget.keypoints.sequence import DEFAULT_MIN_CONFIDENCE
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.sources.base import DEFAULT_QUEUE_FRAMES, SourceFrame
from robot_retarget.sources.keypoints.person_choice import PersonTracker
from robot_retarget.sources.keypoints.wire import decode_keypoints
from robot_retarget.sources.udp_datagram import UdpDatagramSource
from robot_retarget.sources.wire import WireError

DEFAULT_KEYPOINT_PORT = 9751
_BODY = np.array(sorted(BODY_JOINTS), dtype=np.int64)
_NORMALISED_MAX = 1.5  # points all within [0, this] on an image this × 10 px or wider: normalised


class UdpKeypointSource(UdpDatagramSource):
    """Receives COCO-17 packets on ``host:port`` (port 0: any free port)."""

    SCHEME = "udp-keypoints"

    def __init__(
        self,
        model: Agnostic2DRuntime,
        host: str = "127.0.0.1",
        port: int = DEFAULT_KEYPOINT_PORT,
        *,
        token: str = "",
        allow_remote: bool = False,
        min_confidence: float = DEFAULT_MIN_CONFIDENCE,
        nominal_fps: float = 30.0,
        max_queue: int = DEFAULT_QUEUE_FRAMES,
        clock: Callable[[], float] = time.monotonic,
        image_planes: bool = True,
        image_size: tuple[float, float] | None = None,
    ) -> None:
        super().__init__(
            host,
            port,
            token=token,
            allow_remote=allow_remote,
            skeleton=default_canonical_skeleton(),
            nominal_fps=nominal_fps,
            max_queue=max_queue,
            clock=clock,
        )
        self.min_confidence = min_confidence
        self._root = standing_root(self._skeleton)
        self._image_size = image_size
        self._pixels_warned = False
        self._tracker = PersonTracker()
        self._gate = KeypointGate(nominal_fps)
        self._step = model.online()
        # The image size (from --image-size, or each packet's own) puts the principal point
        # at the image centre; a packet's size overrides the one given here.
        self._planes = (
            OnlineReprojection(self._skeleton, fps=nominal_fps, image_size=image_size)
            if image_planes
            else None
        )

    def report_lines(self) -> tuple[str, ...]:
        """The glitch gate's count and the camera the image's planes fitted (stream prints
        them at the end)."""
        gate = (
            f"glitch gate: {self._gate.refused} point(s) no body could have made marked missing",
        )
        return gate + self._camera_lines()

    def _check_pixels(
        self, xy: FloatArray, valid: npt.NDArray[np.bool_], size: tuple[float, float] | None
    ) -> None:
        """Warn once when the points look normalised (every one within [0, 1.5]) while the image
        is pixels wide: they were taken as pixels, the camera fit then made no sense (a focal
        length of 2 px) and the pose came out 13° off, with no word."""
        size = size or self._image_size
        if self._pixels_warned or size is None or min(size) < _NORMALISED_MAX * 10:
            return
        seen = xy[valid]
        if len(seen) < MIN_BODY_POINTS or float(np.abs(seen).max()) > _NORMALISED_MAX:
            return
        self._pixels_warned = True
        self.stats.warn(
            f"source: every keypoint lies within [0, {_NORMALISED_MAX:g}] while the image is "
            f"{size[0]:g}×{size[1]:g} px: are they normalised? Keypoints are pixels (x right, "
            "y down, from the image's top-left corner); multiply by the image size"
        )

    def _camera_lines(self) -> tuple[str, ...]:
        if self._planes is None:
            return ("image planes: off (--no-image-planes)",)
        camera = self._planes.camera
        if camera is None:
            return (
                f"image planes: no camera fitted (less than {MIN_SECONDS:g} s of frames with a "
                "body)",
            )
        if self._planes.principal_px is None:
            principal = (
                "principal point at the performer's mean hip position (no image size: pass "
                "--image-size WxH or send image_size)"
            )
        else:
            x, y = self._planes.principal_px
            principal = f"principal point at the image centre ({x:.0f}, {y:.0f}) px"
        return (
            f"image planes: camera estimated at {math.degrees(camera.elevation_rad):.0f}° "
            f"elevation, focal {camera.focal_px:.0f} px, {principal}",
        )

    def _new_stream(self) -> None:
        """A sender restart: maybe another camera, another performer. Nothing of the old
        stream is carried over (the person followed, the gate's last points, the model's
        context and pooled codes, the camera fitted so far)."""
        self._tracker.reset()
        self._gate.reset()
        self._step.reset()
        if self._planes is not None:
            self._planes.reset()

    def handle_packet(self, data: bytes, recv_s: float) -> SourceFrame | None:
        """Decode, check and lift one datagram; queue and return the frame, or count the drop."""
        self.stats.received += 1
        try:
            pkt = decode_keypoints(data, self.min_confidence)
        except WireError as exc:
            self.stats.drop(exc.reason, str(exc))
            return None
        if not self._authorised(pkt.token):
            return None
        restarts = self._filter.restarts
        if not self._filter.accept(pkt.seq, pkt.t_s):
            return None
        if self._filter.restarts != restarts:
            self._new_stream()
        chosen = self._tracker.choose([(xy, v) for xy, _c, v in pkt.people])
        if chosen is None:  # nobody followed in view: every point missing, nothing guessed
            xy = np.full((NUM_KEYPOINTS, 2), np.nan)
            valid = np.zeros(NUM_KEYPOINTS, dtype=bool)
        else:
            xy, _conf, valid = pkt.people[chosen]
            valid = self._gate.step(xy, valid, pkt.t_s)  # an estimator's glitch: missing
        local = self._step.step(xy, valid)  # the model sees every camera frame, in time
        self._check_pixels(xy, valid, pkt.image_size)
        if self._planes is not None:  # so does the camera fit, as lift_keypoints(causal=True)
            if pkt.image_size is not None:  # a new size resets the camera fitted so far
                self._planes.set_image_size(pkt.image_size)
            local = self._planes.step(local, np.where(valid[:, None], xy, np.nan))
        if int(valid[_BODY].sum()) < MIN_BODY_POINTS:
            # Nobody (or too little of a body) in view: no frame, so the control loop holds
            # and, after 2 s, goes to the safe pose, as for a silent sender.
            self.stats.drop("no_person")
            return None
        return self._deliver(SourceFrame(local, self._root.copy(), pkt.t_s, pkt.seq, recv_s))
