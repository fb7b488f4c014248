"""Pieces shared by the recorded and the live page: the server, world set-up, a stick figure.

viser is imported only when :func:`start_server` runs (through
:func:`robot_retarget.viewer.dependency.require_viser`), so importing this module never
imports viser.
"""

from __future__ import annotations

import contextlib
import socket
import sys
from typing import Any

import numpy as np
import numpy.typing as npt

from robot_retarget.errors import RetargetError
from robot_retarget.viewer.dependency import require_viser

ROBOT_RGB: tuple[int, int, int] = (255, 110, 0)  # orange: the browser test looks for it
PERFORMER_RGB: tuple[int, int, int] = (40, 110, 230)
MEASURED_RGB: tuple[int, int, int] = (60, 170, 60)


def start_server(host: str, port: int) -> Any:
    """A viser server on ``host:port`` (the next free port if busy; 0: any free port). viser
    prints a banner when it starts and a line when it stops: they go to stderr, so stdout stays
    the program's own (``bench --json`` prints JSON lines there)."""
    viser = require_viser()
    _check_address(host)
    with contextlib.redirect_stdout(sys.stderr):
        return viser.ViserServer(host=host, port=port, verbose=False)


def _check_address(host: str) -> None:
    """An address this machine cannot serve on is a one-line error here: viser would fail in
    its own thread and leave the page silently unserved."""
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
        family, kind, proto, _name, address = infos[0]
        with socket.socket(family, kind, proto) as probe:
            probe.bind(address)
    except OSError as exc:
        raise ViewerServeError(
            f"cannot serve the viewer on {host!r} ({exc.strerror or exc}): use an address of "
            "this machine (127.0.0.1, or 0.0.0.0 for every interface)"
        ) from None


class ViewerServeError(RetargetError):
    """The viewer's address cannot be served on."""


def stop_server(server: Any) -> None:
    with contextlib.redirect_stdout(sys.stderr):
        server.stop()


def setup_world(server: Any, *, size_m: float, look_at: npt.ArrayLike, view_m: float) -> None:
    """Z-up world, a ground grid ``size_m`` across and a camera that frames a box ``view_m``
    across around ``look_at``."""
    server.scene.set_up_direction("+z")
    cell = 0.1 if size_m < 4.0 else 0.5
    server.scene.add_grid(
        "/ground", width=size_m, height=size_m, plane="xy", cell_size=cell, section_size=5 * cell
    )
    target = np.asarray(look_at, dtype=np.float64)
    reach = max(0.7 * view_m, 0.3)
    server.initial_camera.look_at = tuple(target)
    server.initial_camera.position = tuple(target + np.array([1.2, -1.6, 0.6]) * reach)


class StickFigure:
    """Line segments and joint dots under one scene node, moved frame by frame."""

    def __init__(
        self,
        server: Any,
        name: str,
        segments: npt.ArrayLike,
        rgb: tuple[int, int, int],
        *,
        thickness_m: float,
        dots: bool = True,
    ) -> None:
        seg = np.asarray(segments, dtype=np.float32)
        self._links = server.scene.add_line_segments(
            f"{name}/links", points=seg, colors=rgb, thickness=thickness_m
        )
        # Dots on the joints: one more scene message per update (a live overlay goes without).
        self._joints = None
        if dots:
            self._joints = server.scene.add_point_cloud(
                f"{name}/joints",
                points=seg.reshape(-1, 3),
                colors=rgb,
                point_size=1.6 * thickness_m,
                point_shape="circle",
            )

    def update(self, segments: npt.ArrayLike) -> None:
        seg = np.asarray(segments, dtype=np.float32)
        self._links.points = seg
        if self._joints is not None:
            self._joints.points = seg.reshape(-1, 3)

    @property
    def visible(self) -> bool:
        return bool(self._links.visible)

    @visible.setter
    def visible(self, value: bool) -> None:
        self._links.visible = value
        if self._joints is not None:
            self._joints.visible = value
