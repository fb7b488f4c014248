"""doctor: latency timer advice, bus check against the config, the CLI command."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import pytest

from robot_retarget.cli import doctor_cmd
from robot_retarget.hardware import doctor
from robot_retarget.hardware.servo_registers import EepromLockedError, joint_tick_range
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.dxl_bus import SimulatedBus


def test_latency_timer_read_and_advice(tmp_path: Path) -> None:
    (tmp_path / "ttyUSB0").mkdir()
    (tmp_path / "ttyUSB0" / "latency_timer").write_text("16\n")
    assert doctor.latency_timer_ms("/dev/ttyUSB0", tmp_path) == 16
    advice = doctor.latency_advice("/dev/ttyUSB0", 16, tmp_path)
    assert "16 ms" in advice
    assert "echo 1 | sudo tee" in advice
    assert "udev" in advice
    assert "good" in doctor.latency_advice("/dev/ttyUSB0", 1, tmp_path)
    assert doctor.latency_timer_ms("/dev/ttyACM0", tmp_path) is None
    acm = tmp_path / "ttyACM0"  # a serial device that is there, without FTDI's timer
    acm.write_text("")
    assert "not an FTDI" in doctor.latency_advice(str(acm), None, tmp_path)
    # A port that is not there is named as such, not as "not an FTDI adapter".
    gone = doctor.latency_advice(str(tmp_path / "ttyUSB9"), None, tmp_path)
    assert "no such device" in gone
    assert "FTDI" not in gone


def test_check_bus_finds_missing_unexpected_and_mismatched(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus]
) -> None:
    bus_cfg = op3.buses[0]
    sim = op3_sim[bus_cfg.name]
    missing = op3.joints[0].servo_id
    del sim.servos[missing]
    sim.servos[op3.joints[1].servo_id]._put("model_number", 1200)
    report = doctor.check_bus(op3, bus_cfg, sim.port or "", cycles=20)
    assert report.missing == [missing]
    assert report.mismatched == [(op3.joints[1].servo_id, "XM430-W350", 1200)]
    assert not report.ok
    assert report.cycle is not None
    assert report.cycle.runs == 20
    assert "fast sync read" in report.cycle_mode
    sim.settle()
    assert not any(s.torque_on for s in sim.servos.values())  # nothing moved


def test_doctor_command_reports_ok(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], capsys: pytest.CaptureFixture[str]
) -> None:
    if op3.source_path is None:
        pytest.skip("configs/robots/op3.yaml not available to the loader yet")
    port = op3_sim[op3.buses[0].name].port
    parser = argparse.ArgumentParser()
    doctor_cmd.configure(parser)
    code = doctor_cmd.run(
        parser.parse_args(["--robot", "op3", "--port", port or "", "--cycles", "10"])
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"found {op3.num_joints} servo(s)" in out
    assert "cycle" in out
    assert "doctor: OK" in out


def test_doctor_command_without_robot_lists_ports(capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser()
    doctor_cmd.configure(parser)
    assert doctor_cmd.run(parser.parse_args([])) == 0
    assert "serial ports:" in capsys.readouterr().out


def test_model_names() -> None:
    assert doctor.model_name(1020) == "XM430-W350"
    assert doctor.model_name(9999) == "model 9999"


def test_poppy_bus_check(poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus]) -> None:
    cfg = replace(poppy)
    for bus_cfg in cfg.buses:
        report = doctor.check_bus(cfg, bus_cfg, poppy_sim[bus_cfg.name].port or "", cycles=5)
        assert report.ok
        assert report.cycle is not None
        assert len(report.found) == sum(j.bus == bus_cfg.name for j in cfg.joints)


def test_doctor_reports_and_fixes_registers_left_by_other_tools(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus]
) -> None:
    bus_cfg = op3.buses[0]
    sim = op3_sim[bus_cfg.name]
    knee = next(j for j in op3.joints if j.name == "l_knee")
    sim.servos[knee.servo_id]._put("homing_offset", 77)
    report = doctor.check_bus(op3, bus_cfg, sim.port or "", cycles=0)
    assert not report.ok
    assert [(f.servo_id, f.register, f.found) for f in report.register_mismatches] == [
        (knee.servo_id, "homing_offset", 77)
    ]
    fixed = doctor.check_bus(op3, bus_cfg, sim.port or "", cycles=0, fix_registers=True)
    assert fixed.ok
    assert [f.register for f in fixed.fixed] == ["homing_offset"]
    assert sim.servos[knee.servo_id].get("homing_offset") == 0


def test_doctor_command_lists_registers_per_servo_and_fixes_them(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], capsys: pytest.CaptureFixture[str]
) -> None:
    if op3.source_path is None:
        pytest.skip("configs/robots/op3.yaml not available to the loader yet")
    sim = op3_sim[op3.buses[0].name]
    knee = next(j for j in op3.joints if j.name == "l_knee")
    sim.servos[knee.servo_id]._put("drive_mode", 1)  # LeRobot's reverse bit
    parser = argparse.ArgumentParser()
    doctor_cmd.configure(parser)
    args = ["--robot", "op3", "--port", sim.port or "", "--cycles", "0"]
    assert doctor_cmd.run(parser.parse_args(args)) == 1
    out = capsys.readouterr().out
    lines = [line.strip() for line in out.splitlines() if line.strip().startswith("ID ")]
    assert len(lines) == op3.num_joints  # one line per servo
    assert f"ID {knee.servo_id} (l_knee): MISMATCH drive_mode = 1, expected 0" in out
    assert sum("OK (min_position_limit 0, max_position_limit 4095" in x for x in lines) == 19
    assert doctor_cmd.run(parser.parse_args([*args, "--fix-registers"])) == 0
    out = capsys.readouterr().out
    assert f"FIXED ID {knee.servo_id} (l_knee) drive_mode: 1 → 0" in out
    assert "doctor: OK" in out
    assert sim.servos[knee.servo_id].get("drive_mode") == 0


def test_doctor_fixes_what_it_can_and_names_a_locked_servo(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus]
) -> None:
    """Two servos of one bus with pypot-like limits, one of them locked: the other is fixed,
    the locked one is named (not written) and the bus is not OK."""
    bus_cfg = poppy.buses[0]
    first, second = [j for j in poppy.joints if j.bus == bus_cfg.name][:2]
    sim = poppy_sim[bus_cfg.name]
    for j in (first, second):
        lo, _hi = joint_tick_range(j)
        sim.servos[j.servo_id]._put("cw_angle_limit", lo + 10)
    sim.servos[first.servo_id]._put("lock", 1)
    report = doctor.check_bus(poppy, bus_cfg, sim.port or "", cycles=0, fix_registers=True)
    [locked] = report.fix_errors
    assert isinstance(locked, EepromLockedError)
    assert (locked.servo_id, locked.joint, locked.register) == (first.servo_id, first.name, "lock")
    assert [(f.servo_id, f.register) for f in report.register_mismatches] == [
        (first.servo_id, "cw_angle_limit")
    ]
    assert [(f.servo_id, f.register) for f in report.fixed] == [(second.servo_id, "cw_angle_limit")]
    assert sim.servos[second.servo_id].get("cw_angle_limit") == 0
    assert not report.ok


def test_a_servo_whose_replies_were_lost_in_the_scan_is_asked_again(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus]
) -> None:
    """Two replies of one servo lost during the scan (its ping and the bus's retry): it was
    reported MISSING though it answers; it is asked once more, alone, after the scan."""
    bus_cfg = poppy.buses[0]
    sim = poppy_sim[bus_cfg.name]
    sid = next(j.servo_id for j in poppy.joints if j.bus == bus_cfg.name)
    sim.faults.only_id, sim.faults.drop_replies = sid, 2
    report = doctor.check_bus(poppy, bus_cfg, sim.port or "", cycles=0)
    assert report.missing == []
    assert sid in report.found
    sim.faults.only_id, sim.faults.drop_replies = sid, 10_000  # really gone: still missing
    report = doctor.check_bus(poppy, bus_cfg, sim.port or "", cycles=0)
    assert report.missing == [sid]
    sim.faults.drop_replies = 0
