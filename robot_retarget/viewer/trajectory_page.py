"""The ``view`` page: a recorded robot trajectory (and optionally its performer) in a browser.

The robot stands at the trajectory's floating-base pose on a ground grid, the performer beside
it; a timeline (play / pause, a frame slider, a speed choice) drives both, and per-joint plots
show the chosen joint's angle against its limits and its speed against its velocity limit.
A background thread advances playback at :data:`PLAYBACK_HZ`; :meth:`TrajectoryPage.show_frame`
lets a program (or a test) pause and set the frame itself.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.config import RobotConfig
from robot_retarget.viewer.robot_match import joint_angles_for
from robot_retarget.viewer.robot_scene import (
    PERFORMER_RGB,
    ROBOT_RGB,
    StickFigure,
    setup_world,
    start_server,
    stop_server,
)
from robot_retarget.viewer.scene import PerformerFigure, RobotFigure
from robot_retarget.viewer.timeline import SPEEDS, Timeline

PLAYBACK_HZ = 30.0
_PLAY, _PAUSE = "Play", "Pause"


class TrajectoryPage:
    """Serve one trajectory on ``host:port`` (viser takes the next free port if it is busy)."""

    def __init__(
        self,
        config: RobotConfig,
        trajectory: RobotTrajectory,
        performer: PerformerFigure | None = None,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        autoplay: bool = True,
    ) -> None:
        self.config = config
        self.trajectory = trajectory
        self.performer = performer
        self.figure = RobotFigure(config)
        q = joint_angles_for(config, trajectory)
        n = trajectory.num_frames
        root_pos = trajectory.root_pos if trajectory.root_pos is not None else np.zeros((n, 3))
        if trajectory.root_quat is None:
            # No floating base in the file: stand the init pose's lowest point on the ground.
            root_pos = root_pos - np.array([0.0, 0.0, float(self.figure.points(q[0])[:, 2].min())])
        # The pose is computed per frame drawn (~0.2 ms): a long clip's every segment at once
        # would cost hundreds of MB.
        self._q = q
        self._root_pos = root_pos
        self._root_quat = trajectory.root_quat
        self._times = trajectory.times_s()
        self.timeline = Timeline(n, trajectory.fps, trajectory.t0, playing=autoplay)

        self.server = start_server(host, port)
        # The grid covers the base's path, a robot's height around it, and the performer.
        reach = self.figure.height_m()
        pts = np.vstack([root_pos - reach, root_pos + reach])
        if performer is not None:
            pts = np.vstack([pts, performer.points.reshape(-1, 3)])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        size = float(max(2.0, 2.0 * np.ceil(np.max(np.abs([lo[:2], hi[:2]])) + 0.5)))
        # Frame the first pose of both figures; the grid covers the whole path.
        first = self.robot_segments(0).reshape(-1, 3)
        if performer is not None:
            first = np.vstack([first, performer.points[0]])
        f_lo, f_hi = first.min(axis=0), first.max(axis=0)
        setup_world(
            self.server,
            size_m=size,
            look_at=(f_lo + f_hi) / 2.0,
            view_m=float(np.linalg.norm(f_hi - f_lo)),
        )
        thickness = 0.025 * self.figure.height_m()
        self._robot = StickFigure(
            self.server, "/robot", self.robot_segments(0), ROBOT_RGB, thickness_m=thickness
        )
        self._human: StickFigure | None = None
        if performer is not None:
            self._human = StickFigure(
                self.server,
                "/performer",
                performer.segments(performer.frame_at(self._times[0])),
                PERFORMER_RGB,
                thickness_m=thickness,
            )
        self._build_gui(q)
        self._lock = threading.Lock()  # one frame change at a time (GUI thread vs play thread)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._play_loop, name="view-playback", daemon=True)
        self._thread.start()

    # --- public -----------------------------------------------------------------------------

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    @property
    def port(self) -> int:
        return int(self.server.get_port())

    def client_count(self) -> int:
        return len(self.server.get_clients())

    def show_frame(self, frame: int) -> int:
        """Pause and show ``frame`` (clamped); returns the frame shown."""
        self.timeline.playing = False
        self._slider.value = self.timeline.seek(frame)
        self._draw(self.timeline.frame)  # drawn even when the slider already showed it
        return self.timeline.frame

    def robot_segments(self, frame: int) -> FloatArray:
        """The robot's segments (E, 2, 3) in the world at ``frame``."""
        rot = None if self._root_quat is None else self._root_quat[frame]
        return self.figure.segments(self._q[frame], self._root_pos[frame], rot)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        stop_server(self.server)

    def __enter__(self) -> TrajectoryPage:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- page -------------------------------------------------------------------------------

    def _build_gui(self, q: FloatArray) -> None:
        gui = self.server.gui
        n = self.timeline.num_frames
        with gui.add_folder("Timeline"):
            self._play = gui.add_button_group("Playback", (_PLAY, _PAUSE))
            self._slider = gui.add_slider(
                "Frame", min=0, max=max(n - 1, 1), step=1, initial_value=0
            )
            self._speed = gui.add_dropdown(
                "Speed", tuple(f"{s:g}x" for s in SPEEDS), initial_value="1x"
            )
            self._time = gui.add_text("Time (s)", f"{self.timeline.time_s:.3f}", disabled=True)
        self._play.on_click(self._on_play)
        self._slider.on_update(self._on_slider)
        self._speed.on_update(self._on_speed)
        if self._human is not None:
            self._show_performer = gui.add_checkbox("Show performer", True)
            self._show_performer.on_update(self._on_show_performer)

        self._joint_q = q
        with gui.add_folder("Joint plots"):
            self._joint = gui.add_dropdown(
                "Joint", self.config.joint_names, initial_value=self.config.joint_names[0]
            )
            self._angle_plot, self._speed_plot = self._add_plots(0)
        self._joint.on_update(lambda _: self._set_plot_joint())

    def _plot_data(self, j: int) -> tuple[tuple[FloatArray, ...], tuple[FloatArray, ...]]:
        t = self._times
        q = self._joint_q[:, j]
        vel = np.gradient(q, 1.0 / self.trajectory.fps) if q.size > 1 else np.zeros_like(q)
        joint = self.config.joints[j]
        ones = np.ones_like(t)
        angle = (t, q, ones * joint.lower_rad, ones * joint.upper_rad)
        vmax = joint.max_velocity_rad_s
        return angle, (t, vel, ones * -vmax, ones * vmax)

    def _add_plots(self, j: int) -> tuple[Any, Any]:
        from viser import uplot

        angle, speed = self._plot_data(j)
        limit = uplot.Series(label="limit", stroke="#c03030", width=1.0, dash=(6.0, 4.0))
        time_axis = uplot.Series(label="t (s)")
        scales: dict[str, uplot.Scale] = {"x": uplot.Scale(time=False)}  # seconds, not dates
        angle_plot = self.server.gui.add_uplot(
            angle,
            (time_axis, uplot.Series(label="q (rad)", stroke="#c85a00", width=1.5), limit, limit),
            title="angle (rad) and joint limits",
            scales=scales,
            aspect=2.0,
        )
        speed_plot = self.server.gui.add_uplot(
            speed,
            (
                time_axis,
                uplot.Series(label="dq/dt (rad/s)", stroke="#2860d0", width=1.5),
                limit,
                limit,
            ),
            title="speed (rad/s) and velocity limit",
            scales=scales,
            aspect=2.0,
        )
        return angle_plot, speed_plot

    def _set_plot_joint(self) -> None:
        j = self.config.joint_names.index(self._joint.value)
        angle, speed = self._plot_data(j)
        self._angle_plot.data = angle
        self._speed_plot.data = speed

    def _on_show_performer(self, _: Any) -> None:
        if self._human is not None:
            self._human.visible = bool(self._show_performer.value)

    def _on_play(self, _: Any) -> None:
        self.timeline.playing = self._play.value == _PLAY

    def _on_speed(self, _: Any) -> None:
        self.timeline.speed = float(str(self._speed.value).rstrip("x"))

    def _on_slider(self, _: Any) -> None:
        frame = int(self._slider.value)
        if frame != self.timeline.frame:
            self.timeline.seek(frame)
        self._draw(frame)

    def _draw(self, frame: int) -> None:
        with self._lock, self.server.atomic():
            self._robot.update(self.robot_segments(frame))
            t = float(self._times[frame])
            if self._human is not None and self.performer is not None:
                self._human.update(self.performer.segments(self.performer.frame_at(t)))
            self._time.value = f"{t:.3f}"

    def _play_loop(self) -> None:
        period = 1.0 / PLAYBACK_HZ
        last = time.perf_counter()
        while not self._stop.wait(period):
            now = time.perf_counter()
            if self.timeline.playing:
                frame = self.timeline.advance(now - last)
                self._slider.value = frame  # draws through _on_slider
            last = now
