"""``doctor``: a missing port is a one-line error, and the ``--port BUS=PATH`` syntax of
``stream`` (the old ``--bus`` still works) checked on Poppy's two simulated buses."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from robot_retarget.cli import doctor_cmd
from robot_retarget.cli.main import main
from robot_retarget.cli.port_args import PORT_HELP, PortNotFoundError
from robot_retarget.errors import HardwareError
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.robot_bus import SimulatedRobotBus

TIME_LIMIT_S = 90


def _run(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    doctor_cmd.configure(parser)
    return doctor_cmd.run(parser.parse_args(list(argv)))


def test_missing_port_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["doctor", "--port", "/dev/nonexistent"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""  # refused before anything else
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: serial port /dev/nonexistent does not exist")
    with pytest.raises(PortNotFoundError) as e:
        _run("--robot", "op3", "--port", "/dev/nonexistent")
    assert e.value.port == "/dev/nonexistent"


def test_bus_names_need_a_robot_and_must_exist() -> None:
    with pytest.raises(HardwareError, match="needs --robot"):
        _run("--port", "upper_body=/dev/null")
    with pytest.raises(HardwareError, match="give --port BUS=PATH"):
        _run("--robot", "poppy_humanoid", "--port", "/dev/null")
    with pytest.raises(HardwareError, match="no bus 'legs'"):
        _run("--robot", "poppy_humanoid", "--port", "legs=/dev/null")
    with pytest.raises(HardwareError, match="--bus legs"):
        _run("--robot", "poppy_humanoid", "--bus", "legs")


def test_servo_options_need_a_robot_and_the_port_list_says_nothing_was_checked(
    capsys: pytest.CaptureFixture[str],
) -> None:
    for option in (["--cycles", "5"], ["--fix-registers"], ["--scan-all"]):
        with pytest.raises(HardwareError, match=f"{option[0]}: about the servos.*add --robot"):
            _run(*option)
    assert capsys.readouterr().out == ""  # refused before the port list
    assert _run() == 0
    assert "no servo was checked (add --robot R" in capsys.readouterr().out


def test_cycles_zero_skips_the_timing_and_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    config = load_robot_config("op3")
    with SimulatedRobotBus(config) as sim:
        assert _run("--robot", "op3", "--port", sim.ports["main"], "--cycles", "0") == 0
    out = capsys.readouterr().out
    assert "cycle: not timed (--cycles 0)" in out
    assert "median" not in out
    with pytest.raises(SystemExit):
        _run("--robot", "op3", "--cycles", "-1")


def test_two_buses_with_the_stream_syntax(capsys: pytest.CaptureFixture[str]) -> None:
    config = load_robot_config("poppy_humanoid")
    with SimulatedRobotBus(config) as sim:
        upper, lower = sim.ports["upper_body"], sim.ports["lower_body"]
        both = _run("--robot", "poppy_humanoid", "--port", f"upper_body={upper}",
                    "--port", f"lower_body={lower}", "--cycles", "3")  # fmt: skip
        out_both = capsys.readouterr().out
        one = _run("--robot", "poppy_humanoid", "--port", f"lower_body={lower}", "--cycles", "3")
        out_one = capsys.readouterr().out
        old = _run("--robot", "poppy_humanoid", "--bus", "upper_body", "--port", upper,
                   "--cycles", "3")  # fmt: skip
        out_old = capsys.readouterr()
    assert both == 0, out_both
    assert f"bus upper_body: {upper}" in out_both
    assert f"bus lower_body: {lower}" in out_both
    assert "doctor: OK" in out_both
    assert one == 0, out_one
    assert "bus upper_body" not in out_one  # only the buses named are checked
    assert f"bus lower_body: {lower}" in out_one
    assert old == 0, out_old.out
    assert f"bus upper_body: {upper}" in out_old.out
    assert "bus lower_body" not in out_old.out
    assert "--bus is deprecated; use --port BUS=PATH" in out_old.err


def test_a_default_port_that_cannot_be_opened_says_where_it_came_from(
    missing_default_ports: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without --port doctor opens the config's default_port: the error says so and which
    --port names another."""
    tmp_path = missing_default_ports
    assert _run("--robot", "op3", "--cycles", "1") == 1
    out = capsys.readouterr().out
    assert f"{tmp_path / 'tty_main'} is the robot config's default port for bus main" in out
    assert "give --port PATH;" in out
    assert _run("--robot", "poppy_humanoid", "--port", "upper_body=/dev/null") == 1
    out = capsys.readouterr().out
    assert "default port" not in out  # a port the user named is not the config's
    assert _run("--robot", "poppy_humanoid", "--bus", "lower_body") == 1
    out = capsys.readouterr().out
    assert f"{tmp_path / 'tty_lower_body'} is the robot config's default port" in out
    assert "give --port lower_body=PATH;" in out


def test_stream_and_doctor_document_the_same_port_syntax() -> None:
    from robot_retarget.cli import stream_cmd

    helps = []
    for module in (doctor_cmd, stream_cmd):
        parser = argparse.ArgumentParser()
        module.configure(parser)
        action = next(a for a in parser._actions if "--port" in a.option_strings)
        helps.append((action.help, action.metavar, type(action).__name__))
    assert [h[1:] for h in helps] == [h[1:] for h in helps[1:] + helps[:1]]
    for text, _, _ in helps:  # the same syntax; each says what it does without --port
        assert str(text).startswith(PORT_HELP)
        assert "default_port from the robot config's buses" in str(text)
    assert "BUS=PATH" in str(helps[0][0])


def test_servos_that_do_not_answer_get_the_likely_causes(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Servo 6 moved onto servo 9's ID: both go silent (their replies collide), and doctor
    said only MISSING [6, 9]; now it names the causes, two servos on one ID among them."""
    from robot_retarget.hardware.bus import buses_from_config
    from robot_retarget.hardware.control_table import control_table

    config = load_robot_config("op3")
    with SimulatedRobotBus(config) as sim:
        port = sim.ports["main"]
        bus = buses_from_config(config, {"main": port})["main"]
        bus.open()
        try:
            reg = control_table(config.joints[0].servo_model)["id"]
            bus.write(6, reg.address, bytes([9]))
        finally:
            bus.close()
        assert _run("--robot", "op3", "--port", port, "--cycles", "0") == 1
    out = capsys.readouterr().out
    assert "MISSING (in config, no answer): [6, 9]" in out
    assert "two servos on one ID (their replies collide" in out
