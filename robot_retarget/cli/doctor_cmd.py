"""``doctor``: is the serial setup fit to drive a robot? Ports, servos, latency, cycle time, and
per servo the EEPROM other tools leave behind (limits, Homing Offset, Drive Mode;
``--fix-registers`` writes the values the config expects).

Ports use the same syntax as ``stream`` (robot_retarget.cli.port_args): ``--port PATH`` for a
one-bus robot, ``--port BUS=PATH`` once per bus otherwise; with ``--port`` only the buses it
names are checked, without it every bus at its default port. ``--bus NAME`` (old syntax,
deprecated) still works: it checks that bus, and a plain ``--port PATH`` is taken as
``NAME=PATH``. A port that does not exist is a one-line error (exit code 1) before anything is
checked; the exit code is 1 when a check finds a problem.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from robot_retarget.cli.port_args import add_port_argument, check_ports_exist, split_port
from robot_retarget.errors import HardwareError
from robot_retarget.number_args import non_negative_int

if TYPE_CHECKING:
    from robot_retarget.robot.config import RobotConfig

NAME = "doctor"
HELP = "Check serial ports, servos on a bus vs the robot config, FTDI latency and cycle time."
CYCLES = 200


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", help="robot config name or YAML path: ping and compare")
    add_port_argument(
        parser,
        "default: every bus at its default_port from the robot config's buses; with --port, "
        "only the buses named",
    )
    parser.add_argument(
        "--bus", help="deprecated: use --port BUS=PATH (checks only this bus of the robot)"
    )
    parser.add_argument(
        "--cycles",
        type=non_negative_int,
        default=None,
        help=f"with --robot: timed write+read cycles (default {CYCLES}; 0: no timing)",
    )
    parser.add_argument(
        "--fix-registers",
        action="store_true",
        help="write the expected angle/position limits, Homing Offset and Drive Mode where "
        "another tool left other values (torque off; EEPROM)",
    )
    parser.add_argument(
        "--scan-all",
        action="store_true",
        help="Protocol 1.0: ping every ID 0–252, not only the config's",
    )


def _port_items(args: argparse.Namespace) -> list[str]:
    """``--port`` items, with the deprecated ``--bus NAME`` folded in (``PATH`` → ``NAME=PATH``)."""
    items = list(args.port)
    if args.bus is not None:
        print("warning: --bus is deprecated; use --port BUS=PATH", file=sys.stderr)
        items = [item if "=" in item else f"{args.bus}={item}" for item in items]
    return items


def run(args: argparse.Namespace) -> int:
    from robot_retarget.hardware import doctor
    from robot_retarget.hardware.servo_registers import servo_summary

    ports = doctor.serial_ports()
    items = _port_items(args)
    # Every argument checked before anything is printed or opened.
    check_ports_exist(items, [info.device for info in ports])
    config: RobotConfig | None = None
    given: dict[str, str] = {}
    if args.robot:
        from robot_retarget.pipeline.backends import parse_ports
        from robot_retarget.robot.loader import load_robot_config

        config = load_robot_config(args.robot)
        names = [b.name for b in config.buses]
        if args.bus is not None and args.bus not in names:
            raise HardwareError(
                f"--bus {args.bus}: robot {config.name} has no such bus; buses: {names}"
            )
        # Unknown bus, a plain PATH on several buses, two named buses on one port.
        given = parse_ports(config, items, all_buses=False)
    else:
        named = [item for item in items if split_port(item)[0] is not None]
        if named or args.bus is not None:
            what = f"--port {named[0]}" if named else f"--bus {args.bus}"
            raise HardwareError(
                f"{what}: naming a bus needs --robot R (the robot config defines the buses)"
            )
        servo_options = [
            option
            for option, given in (
                ("--cycles", args.cycles is not None),
                ("--fix-registers", args.fix_registers),
                ("--scan-all", args.scan_all),
            )
            if given
        ]
        if servo_options:
            raise HardwareError(
                f"{', '.join(servo_options)}: about the servos, which doctor checks only with "
                "--robot R (the robot config says which servos to expect); add --robot"
            )
    print("serial ports:")
    if not ports:
        print("  (none found: is the adapter plugged in?)")
    for info in ports:
        print(f"  {info.device}  {info.description}  [{info.hwid}]")
        print(f"    {doctor.latency_advice(info.device, doctor.latency_timer_ms(info.device))}")
    if config is None:
        for item in items:
            print(doctor.latency_advice(item, doctor.latency_timer_ms(item)))
        print(
            "doctor: serial ports listed; no servo was checked (add --robot R to ping the "
            "servos and compare them with the robot config)"
        )
        return 0

    from robot_retarget.pipeline.backends import default_port_hint

    wanted = set(given) | ({args.bus} if args.bus is not None else set())
    buses = [b for b in config.buses if not wanted or b.name in wanted]
    ok = True
    for bus_cfg in buses:
        port = given.get(bus_cfg.name, bus_cfg.default_port)
        hint = "" if bus_cfg.name in given else default_port_hint(config, bus_cfg.name)
        print(f"bus {bus_cfg.name}: {port}, Protocol {bus_cfg.protocol}, {bus_cfg.baud_rate} bps")
        print(f"  {doctor.latency_advice(port, doctor.latency_timer_ms(port))}")
        try:
            report = doctor.check_bus(
                config,
                bus_cfg,
                port,
                cycles=CYCLES if args.cycles is None else args.cycles,
                scan_all=args.scan_all,
                fix_registers=args.fix_registers,
                port_hint=hint,
            )
        except HardwareError as exc:
            print(f"  error: {exc}")
            ok = False
            continue
        found = ", ".join(f"{i}:{doctor.model_name(m)}" for i, m in sorted(report.found.items()))
        print(f"  found {len(report.found)} servo(s): {found or '-'}")
        if report.missing:
            print(f"  MISSING (in config, no answer): {report.missing}")
            print(
                "    no answer: unpowered, unplugged, another baud rate or protocol, or two "
                "servos on one ID (their replies collide, so neither answers); to find a "
                "servo's ID, connect it alone and run doctor (--scan-all on Protocol 1.0)"
            )
        if report.unexpected:
            print(f"  not in config: {report.unexpected}")
        for sid, expected, got in report.mismatched:
            print(f"  MODEL MISMATCH ID {sid}: config {expected}, servo {doctor.model_name(got)}")
        for f in report.fixed:
            print(f"  FIXED ID {f.servo_id} ({f.joint}) {f.register}: {f.found} → {f.fix}")
        for problem in report.fix_errors:
            print(f"  NOT FIXED: {problem}")
        by_servo = report.registers_by_servo()
        if by_servo:
            bad = report.register_mismatches
            verdict = f"{len(bad)} mismatch(es)" if bad else "OK"
            if bad and not args.fix_registers:
                verdict += "; `doctor --fix-registers` writes them"
            what = (
                "CW/CCW angle limits, status return level"
                if bus_cfg.protocol == 1.0
                else "position limits, homing offset, drive mode, status return level"
            )
            print(f"  registers other tools leave ({what}), per servo: {verdict}")
            for findings in by_servo.values():
                print(f"    {servo_summary(findings)}")
        if report.cycle is None and args.cycles == 0:
            print("  cycle: not timed (--cycles 0)")
        if report.cycle is not None:
            c = report.cycle
            print(
                f"  cycle ({report.cycle_mode}, {c.runs} runs): median {c.median_ms:.3f} ms, "
                f"p99 {c.p99_ms:.3f} ms ({1000.0 / c.median_ms:.0f} Hz)"
            )
        ok = ok and report.ok
    print("doctor: OK" if ok else "doctor: problems found (see above)")
    return 0 if ok else 1
