"""``python -m robot_retarget.sim.dxl_bus --robot op3``: PORT line first, serves the real SDK,
stops on SIGINT."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
from pathlib import Path

import dynamixel_sdk as sdk
import pytest

REPO = Path(__file__).resolve().parents[2]


def test_standalone_bus_serves_the_sdk() -> None:
    try:
        from robot_retarget.robot.loader import load_robot_config

        config = load_robot_config("op3")
    except Exception as exc:  # the YAML is written by another helper
        pytest.skip(f"op3 config not loadable: {exc}")
    proc = subprocess.Popen(
        [sys.executable, "-m", "robot_retarget.sim.dxl_bus", "--robot", "op3"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 15.0)
        assert ready, "no output within 15 s"
        first = proc.stdout.readline().split()
        assert first[0] == "PORT"
        assert first[1].startswith("/dev/")
        port = sdk.PortHandler(first[1])
        assert port.openPort()
        assert port.setBaudRate(config.buses[0].baud_rate)
        ph = sdk.PacketHandler(2.0)
        for j in config.joints:
            assert ph.ping(port, j.servo_id)[:2] == (1020, sdk.COMM_SUCCESS)
        port.closePort()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=5.0) == 0  # stops on SIGINT (TimeoutExpired otherwise)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_an_unknown_robot_is_a_one_line_error() -> None:
    out = subprocess.run([sys.executable, "-m", "robot_retarget.sim.dxl_bus", "--robot", "op4"],
                         capture_output=True, text=True, timeout=60, check=False)  # fmt: skip
    assert out.returncode == 2
    assert out.stderr.startswith("error: no robot config named 'op4'")
    assert "Traceback" not in out.stderr
