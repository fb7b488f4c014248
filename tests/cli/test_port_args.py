"""``--port [BUS=]PATH``: splitting, and refusing a device path that does not exist."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from robot_retarget.cli.port_args import (
    PortNotFoundError,
    add_port_argument,
    check_ports_exist,
    split_port,
)
from robot_retarget.errors import HardwareError


def test_split_port() -> None:
    assert split_port("/dev/ttyUSB0") == (None, "/dev/ttyUSB0")
    assert split_port("upper_body=/dev/ttyACM0") == ("upper_body", "/dev/ttyACM0")


def test_repeatable_option() -> None:
    parser = argparse.ArgumentParser()
    add_port_argument(parser)
    assert parser.parse_args([]).port == []
    args = parser.parse_args(["--port", "a=/dev/x", "--port", "b=/dev/y"])
    assert args.port == ["a=/dev/x", "b=/dev/y"]


def test_missing_ports_are_refused(tmp_path: Path) -> None:
    device = tmp_path / "ttyFAKE0"
    device.write_text("")
    check_ports_exist([str(device), f"lower={device}", "rfc2217://robot.local:4000"])
    with pytest.raises(PortNotFoundError, match=r"ports found: /dev/ttyUSB0\)") as e:
        check_ports_exist([f"lower={tmp_path / 'gone'}"], ["/dev/ttyUSB0"])
    assert isinstance(e.value, HardwareError)
    assert e.value.port == str(tmp_path / "gone")
    assert e.value.available == ("/dev/ttyUSB0",)
    with pytest.raises(PortNotFoundError, match="is the adapter plugged in"):
        check_ports_exist(["/dev/nonexistent"], [])  # the OS lists none


def test_a_folder_is_named_as_a_folder_and_the_ports_found_are_listed(tmp_path: Path) -> None:
    """A folder given as --port was said not to exist; and stream (which passes no list of
    ports) said none was found where doctor listed the ports the OS has."""
    with pytest.raises(PortNotFoundError, match="is a folder, not a serial port") as info:
        check_ports_exist([str(tmp_path)], ["/dev/ttyS0"])
    assert info.value.problem == "is a folder, not a serial port"
    from robot_retarget.hardware.doctor import serial_ports

    listed = [p.device for p in serial_ports()]
    with pytest.raises(PortNotFoundError) as missing:
        check_ports_exist([str(tmp_path / "ttyUSB9")])
    assert list(missing.value.available) == listed
