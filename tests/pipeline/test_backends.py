from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.pipeline.backends import open_backend, parse_ports
from robot_retarget.robot.config import BusConfig, RobotConfig
from robot_retarget.sim.backend import SimBackend


def test_ports_for_one_and_two_buses(op3: RobotConfig) -> None:
    assert parse_ports(op3, ["/dev/ttyX"]) == {"main": "/dev/ttyX"}
    assert parse_ports(op3, ["main=/dev/ttyY"]) == {"main": "/dev/ttyY"}
    with pytest.raises(HardwareError, match="no bus"):
        parse_ports(op3, ["upper=/dev/ttyY"])
    two = dataclasses.replace(
        op3, buses=(op3.buses[0], BusConfig("aux", 2.0, 1_000_000, "/dev/ttyUSB1"))
    )
    with pytest.raises(HardwareError, match="BUS=PATH"):
        parse_ports(two, ["/dev/ttyX"])
    assert parse_ports(two, ["main=/dev/a", "aux=/dev/b"]) == {"main": "/dev/a", "aux": "/dev/b"}
    with pytest.raises(HardwareError, match="was given a port already"):
        parse_ports(two, ["aux=/dev/a", "aux=/dev/b"])  # the second would silently win
    with pytest.raises(HardwareError, match="was given a port already"):
        parse_ports(op3, ["/dev/a", "main=/dev/b"])


def test_two_buses_on_one_port_are_refused(op3: RobotConfig, tmp_path: Path) -> None:
    """Two buses would open one serial line twice and interleave their packets on it."""
    two = dataclasses.replace(
        op3, buses=(op3.buses[0], BusConfig("aux", 2.0, 1_000_000, "/dev/ttyUSB1"))
    )
    with pytest.raises(HardwareError, match=r"buses 'main' and 'aux' would both open /dev/a"):
        parse_ports(two, ["main=/dev/a", "aux=/dev/a"])
    link = tmp_path / "adapter"  # a udev symlink and its target are one port
    link.symlink_to(tmp_path / "ttyUSB7")
    with pytest.raises(HardwareError, match="would both open"):
        parse_ports(two, [f"main={tmp_path / 'ttyUSB7'}", f"aux={link}"])
    # A named port that is another bus's default: both open when streaming ...
    with pytest.raises(HardwareError, match="would both open /dev/ttyUSB1"):
        parse_ports(two, ["main=/dev/ttyUSB1"])
    # ... but doctor checks only the buses named
    assert parse_ports(two, ["main=/dev/ttyUSB1"], all_buses=False) == {"main": "/dev/ttyUSB1"}


def test_open_backend_kinds(op3: RobotConfig) -> None:
    assert isinstance(open_backend(op3, "sim"), SimBackend)
    dxl = open_backend(op3, "dynamixel", ["/dev/does-not-exist"])
    assert isinstance(dxl, DynamixelBackend)
    assert not dxl.handle_signals  # the control loop stops smoothly on Ctrl-C itself
    with pytest.raises(HardwareError, match="unknown backend"):
        open_backend(op3, "gazebo")
