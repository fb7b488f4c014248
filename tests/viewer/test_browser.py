"""The viewer page in a real browser: headless Chromium loads it, the robot is drawn, and the
drawing follows the timeline when Python moves it."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pytest

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.viewer.robot_scene import ROBOT_RGB
from robot_retarget.viewer.scene import RobotFigure
from tests.viewer.chromium import HeadlessChromium

TIME_LIMIT_S = 120
COLOUR_TOLERANCE = 12  # per channel: the lines are unlit, only their anti-aliased edges blend
MIN_ROBOT_PIXELS = 200
MIN_CHANGED_PIXELS = 200
SCENE_FRACTION = 0.7  # the GUI panel sits on the right: count robot pixels left of it
WAIT_S = 45.0

BoolArray = npt.NDArray[np.bool_]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def swinging_trajectory(config: RobotConfig, frames: int = 40) -> RobotTrajectory:
    """Shoulders swing from the init pose to their limit while the base turns 90° and walks."""
    s = np.linspace(0.0, 1.0, frames)[:, None]
    q = np.repeat(config.init_pose[None, :], frames, axis=0)
    for j, joint in enumerate(config.joints):
        if "sho" in joint.name or "shoulder" in joint.name:
            q[:, j] = config.init_pose[j] + s[:, 0] * (joint.upper_rad - config.init_pose[j])
    q = np.clip(q, config.lower, config.upper)
    feet_z = float(RobotFigure(config).points(config.init_pose)[:, 2].min())
    root_pos = np.hstack([0.3 * s, np.zeros_like(s), np.full_like(s, -feet_z)])
    root_quat = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.5 * np.pi * s[:, 0])
    return RobotTrajectory(config.joint_names, q, 25.0, root_pos=root_pos, root_quat=root_quat)


def robot_mask(image: npt.NDArray[np.uint8]) -> BoolArray:
    diff = np.abs(image.astype(np.int16) - np.array(ROBOT_RGB, dtype=np.int16)).max(axis=-1)
    mask = diff <= COLOUR_TOLERANCE
    mask[:, int(SCENE_FRACTION * mask.shape[1]) :] = False
    return mask


def settled_mask(browser: HeadlessChromium, ready: Callable[[BoolArray], bool]) -> BoolArray:
    """Screenshots until the robot mask satisfies ``ready`` and two in a row agree."""
    previous: BoolArray | None = None
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        mask = robot_mask(browser.screenshot())
        if ready(mask) and previous is not None and np.array_equal(mask, previous):
            return mask
        previous = mask
        time.sleep(0.3)
    count = 0 if previous is None else int(previous.sum())
    pytest.fail(f"the page never showed the expected robot within {WAIT_S} s ({count} px)")


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_page_draws_the_robot_and_follows_the_timeline(
    chromium: HeadlessChromium, robot: str
) -> None:
    from robot_retarget.viewer.trajectory_page import TrajectoryPage

    config = load_robot_config(robot)
    trajectory = swinging_trajectory(config)
    with TrajectoryPage(config, trajectory, port=free_port(), autoplay=False) as page:
        page.show_frame(0)
        chromium.open(page.url)
        first = settled_mask(chromium, lambda m: int(m.sum()) >= MIN_ROBOT_PIXELS)
        page.show_frame(trajectory.num_frames - 1)
        last = settled_mask(
            chromium,
            lambda m: (
                int(m.sum()) >= MIN_ROBOT_PIXELS and int((m ^ first).sum()) >= MIN_CHANGED_PIXELS
            ),
        )
    assert first.sum() >= MIN_ROBOT_PIXELS
    assert (first ^ last).sum() >= MIN_CHANGED_PIXELS


def test_pause_in_the_page_stops_playback(chromium: HeadlessChromium) -> None:
    from robot_retarget.viewer.trajectory_page import TrajectoryPage

    config = load_robot_config("op3")
    trajectory = swinging_trajectory(config, frames=400)
    with TrajectoryPage(config, trajectory, port=free_port(), autoplay=True) as page:
        chromium.open(page.url)
        deadline = time.monotonic() + WAIT_S  # playing: the drawing never holds still
        while robot_mask(chromium.screenshot()).sum() < MIN_ROBOT_PIXELS:
            if time.monotonic() > deadline:
                pytest.fail(f"the page never showed the robot within {WAIT_S} s")
            time.sleep(0.3)
        assert page.timeline.playing
        click = (
            "(() => { const b = [...document.querySelectorAll('button')]"
            ".find(e => e.textContent.trim() === 'Pause'); if (b) b.click(); return !!b; })()"
        )
        found = chromium.call("Runtime.evaluate", expression=click, returnByValue=True)
        assert found["result"]["value"] is True
        deadline = time.monotonic() + WAIT_S
        while page.timeline.playing and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not page.timeline.playing
        frame = page.timeline.frame
        time.sleep(0.5)
        assert page.timeline.frame == frame  # paused: the clock stands still
