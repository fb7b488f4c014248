"""Software nobody here wrote, against the simulated buses, 100 sessions out of 100.

- pypot's ``DxlIO`` (Poppy's own library, Protocol 1.0) with its stock Poppy settings
  (``use_sync_read=True``: the USB2AX adapter's SYNC_READ), in its own process, with
  :func:`robot_retarget.sim.pty_serial.keep_pty_output` (see there why a pty needs it);
- a LeRobot-style client on OP3 (Protocol 2.0, ``lerobot_style_client.py``, in its own
  process): the ROBOTIS SDK's GroupSyncWrite / GroupSyncRead, a calibration written as LeRobot
  writes it (Homing_Offset, Drive_Mode), goals and present positions read back in the
  calibrated frame.

pypot is an optional test dependency (``pip install --no-deps pypot==5.0.2``: its Dynamixel
layer needs only numpy and pyserial); without it that test skips with the reason.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.dxl_bus import buses_for_robot

REPO = Path(__file__).resolve().parents[2]
SESSIONS = 100

_PYPOT_SESSIONS = """
import sys
from robot_retarget.sim.pty_serial import keep_pty_output
keep_pty_output()
import pypot.dynamixel as pd

port, ids, sessions = sys.argv[1], [int(i) for i in sys.argv[2].split(",")], int(sys.argv[3])
passed = 0
for k in range(sessions):
    with pd.DxlIO(port, baudrate=1000000, timeout=0.05, use_sync_read=True) as io:
        ok = io.scan(ids) == ids
        io.enable_torque(ids)
        ok &= all(io.is_torque_enabled(ids))
        goal = [(-1) ** k * 4.0 + 0.5 * i for i in range(len(ids))]
        io.set_goal_position(dict(zip(ids, goal)))
        got = io.get_goal_position(ids)
        ok &= len(got) == len(ids) and all(abs(a - b) < 0.5 for a, b in zip(got, goal))
        io.disable_torque(ids)
        ok &= not any(io.is_torque_enabled(ids))
        passed += ok
print(f"PASSED {passed}/{sessions}")
"""


@pytest.mark.skipif(
    importlib.util.find_spec("pypot") is None,
    reason="pypot is not installed (pip install --no-deps pypot==5.0.2)",
)
def test_pypot_drives_the_simulated_poppy_every_time() -> None:
    config = load_robot_config("poppy_humanoid")
    buses = buses_for_robot(config)
    try:
        for name in ("lower_body", "upper_body"):
            bus = buses[name]
            port = bus.start()
            ids = ",".join(str(i) for i in sorted(bus.servos))
            out = subprocess.run(
                [sys.executable, "-c", _PYPOT_SESSIONS, port, ids, str(SESSIONS)],
                cwd=REPO,
                capture_output=True,
                text=True,
                timeout=240,
                check=False,
            )
            assert f"PASSED {SESSIONS}/{SESSIONS}" in out.stdout, (name, out.stdout, out.stderr)
    finally:
        for bus in buses.values():
            bus.stop()


def test_a_lerobot_style_client_drives_the_simulated_op3_every_time() -> None:
    config = load_robot_config("op3")
    buses = buses_for_robot(config)
    bus = buses["main"]
    port = bus.start()
    try:
        out = subprocess.run(
            [sys.executable, str(Path(__file__).with_name("lerobot_style_client.py")), port,
             str(SESSIONS)],
            cwd=REPO, capture_output=True, text=True, timeout=240, check=False,
        )  # fmt: skip
    finally:
        bus.stop()
    assert f"PASSED {SESSIONS}/{SESSIONS} " in out.stdout, (out.stdout, out.stderr)
    # A timed-out reply is retried (as LeRobot does), but a simulator that keeps missing
    # replies is still a failure.
    assert int(out.stdout.split("RETRIES")[1]) <= SESSIONS // 10, out.stdout
