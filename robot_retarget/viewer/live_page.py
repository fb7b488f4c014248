"""The ``stream --view`` page: the robot as the control loop drives it, live.

The control loop only drops a :class:`~robot_retarget.pipeline.live_mailbox.LiveFrame` into a
one-slot mailbox each tick. A publisher thread here reads the newest frame at most
:data:`PUBLISH_HZ` times a second (frames in between are skipped, never queued) and updates
the page: the commanded pose (orange) and, where the backend can report it without touching
the bus, the measured pose (green) over it; the loop's mode (the watchdog's state), input
silence, latency and jitter; what the safety layer clipped; and a rolling plot of one joint's
target, command and measurement against its limits, and of its commanded speed against its
velocity limit.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.pipeline.live_mailbox import LiveFrame, Mailbox
from robot_retarget.robot.config import RobotConfig
from robot_retarget.viewer.robot_scene import (
    MEASURED_RGB,
    ROBOT_RGB,
    StickFigure,
    setup_world,
    start_server,
    stop_server,
)
from robot_retarget.viewer.scene import RobotFigure

PUBLISH_HZ = 30.0
PLOT_EVERY = 3  # publishes per panel and plot update: they refresh at 10 Hz
PLOT_WINDOW_S = 10.0
_CLIP_TOL_RAD = 1e-12

MeasureFn = Callable[[], FloatArray | None]


class LivePage:
    """Serve the live view of ``config`` fed from ``mailbox`` on ``host:port``.

    ``measure``: returns the measured joint angles (rad, config order) without bus traffic of
    its own, or None when it has none; called from the publisher thread only."""

    def __init__(
        self,
        config: RobotConfig,
        mailbox: Mailbox[LiveFrame],
        *,
        measure: MeasureFn | None = None,
        host: str = "127.0.0.1",
        port: int = 8080,
        publish_hz: float = PUBLISH_HZ,
    ) -> None:
        self.config = config
        self.mailbox = mailbox
        self.measure = measure
        self.period_s = 1.0 / min(publish_hz, PUBLISH_HZ)
        self.figure = RobotFigure(config)
        # No floating base live: the robot stands with its init pose's feet on the ground.
        feet_z = float(self.figure.points(config.init_pose)[:, 2].min())
        self._root_pos = np.array([0.0, 0.0, -feet_z])
        standing = self.figure.segments(config.init_pose, self._root_pos)
        self.server = start_server(host, port)
        height = self.figure.height_m()
        setup_world(self.server, size_m=2.0, look_at=(0.0, 0.0, height / 2.0), view_m=1.5 * height)
        thickness = 0.025 * height
        self._commanded = StickFigure(
            self.server, "/commanded", standing, ROBOT_RGB, thickness_m=thickness
        )
        self._measured = StickFigure(
            self.server,
            "/measured",
            standing,
            MEASURED_RGB,
            thickness_m=0.5 * thickness,
            dots=False,
        )
        self._measured.visible = measure is not None
        n = max(int(PLOT_WINDOW_S * min(publish_hz, PUBLISH_HZ)), 2)
        self._history: deque[tuple[float, FloatArray, FloatArray, FloatArray | None]] = deque(
            maxlen=n
        )
        self.published = 0  # frames drawn (the loop's other ticks are skipped, never queued)
        self.publish_s: deque[float] = deque(maxlen=4096)  # time each publish took (thread)
        self._last_news: tuple[str, int] = ("", -1)
        self._build_gui()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._publish_loop, name="view-live", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def shown(self) -> dict[str, str]:
        """What the Live panel shows now, by label."""
        fields = (self._mode, self._silence, self._latency, self._jitter, self._clips)
        out = {f.label: str(f.value) for f in fields}
        out[self._clipped_now.label] = str(self._clipped_now.value)
        return out

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        stop_server(self.server)

    def __enter__(self) -> LivePage:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- page -------------------------------------------------------------------------------

    def _build_gui(self) -> None:
        gui = self.server.gui
        with gui.add_folder("Live"):
            self._mode = gui.add_text("Mode", "waiting", disabled=True)
            self._silence = gui.add_text("Input silent (ms)", "-", disabled=True)
            self._latency = gui.add_text("Latency (ms)", "-", disabled=True)
            self._jitter = gui.add_text("Tick jitter (ms)", "-", disabled=True)
            self._clips = gui.add_text("Safety: commands clipped", "0", disabled=True)
            self._clipped_now = gui.add_text("Clipped now", "-", disabled=True)
            measured = "green, over the command" if self.measure else "not available"
            gui.add_markdown(f"Orange: commanded. Measured: {measured}.")
        with gui.add_folder("Joint plots"):
            names = self.config.joint_names
            self._joint = gui.add_dropdown("Joint", names, initial_value=names[0])
            self._angle_plot, self._speed_plot = self._add_plots()

    def _add_plots(self) -> tuple[Any, Any]:
        from viser import uplot

        scales: dict[str, uplot.Scale] = {"x": uplot.Scale(time=False)}
        limit = uplot.Series(label="limit", stroke="#c03030", width=1.0, dash=(6.0, 4.0))
        t = uplot.Series(label="t (s)")
        empty = np.zeros(2)
        angle = self.server.gui.add_uplot(
            (empty,) * 6,
            (
                t,
                uplot.Series(label="target", stroke="#888888", width=1.0),
                uplot.Series(label="commanded", stroke="#c85a00", width=1.5),
                uplot.Series(label="measured", stroke="#3caa3c", width=1.5),
                limit,
                limit,
            ),
            title="angle (rad): target, commanded, measured, limits",
            scales=scales,
            aspect=2.0,
        )
        speed = self.server.gui.add_uplot(
            (empty,) * 4,
            (t, uplot.Series(label="commanded (rad/s)", stroke="#2860d0", width=1.5), limit, limit),
            title="commanded speed (rad/s) and velocity limit",
            scales=scales,
            aspect=2.0,
        )
        return angle, speed

    # --- publishing -------------------------------------------------------------------------

    def _publish_loop(self) -> None:
        last: LiveFrame | None = None
        while not self._stop.wait(self.period_s):
            frame = self.mailbox.latest()
            if frame is not None and frame is not last:
                last = frame
                t0 = time.perf_counter()
                self._publish(frame)
                self.publish_s.append(time.perf_counter() - t0)

    def _publish(self, frame: LiveFrame) -> None:
        """The pose every publish; the panel and plots every PLOT_EVERY-th (fewer messages:
        the publisher holds the interpreter lock the loop needs for less time)."""
        measured = self.measure() if self.measure is not None else None
        self._history.append((frame.t_s, frame.q_target, frame.q_cmd, measured))
        # A new mode or a new clip is shown at once; the rest can wait for the next refresh.
        news = (frame.mode, frame.commands_clipped) != self._last_news
        self._last_news = (frame.mode, frame.commands_clipped)
        with self.server.atomic():
            self._commanded.update(self.figure.segments(frame.q_cmd, self._root_pos))
            if measured is not None:
                self._measured.update(self.figure.segments(measured, self._root_pos))
            if news or self.published % PLOT_EVERY == 0:
                self._update_panel(frame)
        if self.published % PLOT_EVERY == 0:
            self._update_plots()
        self.published += 1

    def _update_panel(self, frame: LiveFrame) -> None:
        clipped = np.abs(frame.q_target - frame.q_cmd) > _CLIP_TOL_RAD
        names = [n for n, c in zip(self.config.joint_names, clipped, strict=True) if c]
        self._mode.value = frame.mode
        self._silence.value = f"{frame.silence_s * 1e3:.0f}"
        self._latency.value = "-" if np.isnan(frame.latency_s) else f"{frame.latency_s * 1e3:.2f}"
        self._jitter.value = f"{frame.jitter_s * 1e3:.2f}"
        self._clips.value = str(frame.commands_clipped)
        self._clipped_now.value = ", ".join(names) or "-"

    def _update_plots(self) -> None:
        if len(self._history) < 2:
            return
        j = self.config.joint_names.index(self._joint.value)
        joint = self.config.joints[j]
        t = np.array([h[0] for h in self._history])
        t = t - t[-1]  # seconds before now
        target = np.array([h[1][j] for h in self._history])
        cmd = np.array([h[2][j] for h in self._history])
        meas = np.array([np.nan if h[3] is None else h[3][j] for h in self._history])
        speed = np.gradient(cmd, t) if np.all(np.diff(t) > 0) else np.zeros_like(cmd)
        ones = np.ones_like(t)
        self._angle_plot.data = (
            t,
            target,
            cmd,
            meas,
            ones * joint.lower_rad,
            ones * joint.upper_rad,
        )
        vmax = joint.max_velocity_rad_s
        self._speed_plot.data = (t, speed, -vmax * ones, vmax * ones)
