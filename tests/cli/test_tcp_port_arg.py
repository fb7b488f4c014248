"""The viewer's --port / --view-port: a port number argparse checks, and an address the
machine cannot serve on named before the server starts."""

from __future__ import annotations

import argparse

import pytest

from robot_retarget.cli.tcp_port_arg import tcp_port_argument


def test_ports_outside_the_tcp_range_are_argparse_errors() -> None:
    assert tcp_port_argument("0") == 0
    assert tcp_port_argument("8080") == 8080
    for text in ("99999", "-1", "http"):
        with pytest.raises(argparse.ArgumentTypeError):
            tcp_port_argument(text)


def test_an_address_this_machine_lacks_is_a_one_line_error() -> None:
    pytest.importorskip("viser")
    from robot_retarget.errors import RetargetError
    from robot_retarget.viewer.robot_scene import start_server

    with pytest.raises(RetargetError, match=r"cannot serve the viewer on '203\.0\.113\.7'"):
        start_server("203.0.113.7", 0)  # TEST-NET-3: never an address of this machine
