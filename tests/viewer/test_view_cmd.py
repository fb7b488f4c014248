"""``view`` as a user runs it: the robot told by the file, the clip beside it, a page served
until Ctrl-C."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.robot.loader import load_robot_config

TIME_LIMIT_S = 90
REPO = Path(__file__).resolve().parents[2]
CLIP = REPO / "tests" / "fixtures" / "motion" / "tiny_walk.bvh"


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
def test_view_serves_the_page_until_ctrl_c(tmp_path: Path, robot: str) -> None:
    pytest.importorskip("viser", reason="view needs the [view] extra (pip install viser)")
    config = load_robot_config(robot)
    q = np.repeat(config.init_pose[None, :], 10, axis=0)
    path = RobotTrajectory(config.joint_names, q, 50.0).write(tmp_path / "traj.npz")
    proc = subprocess.Popen(
        [sys.executable, str(REPO / "launch.py"), "view", str(path), "--clip", str(CLIP),
         "--port", "0", "--no-browser"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=REPO,
    )  # fmt: skip
    try:
        assert proc.stderr is not None
        url = None
        deadline = time.monotonic() + 60
        while url is None and time.monotonic() < deadline:
            line = proc.stderr.readline()
            if not line:
                break
            found = re.search(r"robot (\S+), 10 frames at 50 fps: (http://\S+)", line)
            if found:
                assert found.group(1) == config.name
                url = found.group(2)
        assert url is not None, "view never printed its address"
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200
            assert b"<html" in page.read().lower()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 130  # Ctrl-C: the CLI's "interrupted"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
