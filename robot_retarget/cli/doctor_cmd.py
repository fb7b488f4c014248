"""``doctor``: is the serial setup fit to drive a robot? Ports, servos, latency, cycle time."""

from __future__ import annotations

import argparse

from robot_retarget.errors import HardwareError

NAME = "doctor"
HELP = "Check serial ports, servos on a bus vs the robot config, FTDI latency and cycle time."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", help="robot config name or YAML path: ping and compare")
    parser.add_argument("--port", help="serial port (default: the bus's default_port)")
    parser.add_argument("--bus", help="only this bus of the robot (needed with --port on 2 buses)")
    parser.add_argument("--cycles", type=int, default=200, help="timed write+read cycles")
    parser.add_argument(
        "--scan-all",
        action="store_true",
        help="Protocol 1.0: ping every ID 0–252, not only the config's",
    )


def run(args: argparse.Namespace) -> int:
    from robot_retarget.hardware import doctor

    ports = doctor.serial_ports()
    print("serial ports:")
    if not ports:
        print("  (none found: is the adapter plugged in?)")
    for info in ports:
        print(f"  {info.device}  {info.description}  [{info.hwid}]")
        print(f"    {doctor.latency_advice(info.device, doctor.latency_timer_ms(info.device))}")
    if not args.robot:
        if args.port:
            print(doctor.latency_advice(args.port, doctor.latency_timer_ms(args.port)))
        return 0

    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config(args.robot)
    buses = [b for b in config.buses if args.bus in (None, b.name)]
    if args.bus and not buses:
        print(f"robot {config.name} has no bus {args.bus!r}: {[b.name for b in config.buses]}")
        return 2
    if args.port and len(buses) > 1:
        print(f"robot {config.name} has {len(buses)} buses: say which one --port is (--bus NAME)")
        return 2
    ok = True
    for bus_cfg in buses:
        port = args.port or bus_cfg.default_port
        print(f"bus {bus_cfg.name}: {port}, Protocol {bus_cfg.protocol}, {bus_cfg.baud_rate} bps")
        print(f"  {doctor.latency_advice(port, doctor.latency_timer_ms(port))}")
        try:
            report = doctor.check_bus(
                config, bus_cfg, port, cycles=args.cycles, scan_all=args.scan_all
            )
        except HardwareError as exc:
            print(f"  error: {exc}")
            ok = False
            continue
        found = ", ".join(f"{i}:{doctor.model_name(m)}" for i, m in sorted(report.found.items()))
        print(f"  found {len(report.found)} servo(s): {found or '-'}")
        if report.missing:
            print(f"  MISSING (in config, no answer): {report.missing}")
        if report.unexpected:
            print(f"  not in config: {report.unexpected}")
        for sid, expected, got in report.mismatched:
            print(f"  MODEL MISMATCH ID {sid}: config {expected}, servo {doctor.model_name(got)}")
        if report.cycle is not None:
            c = report.cycle
            print(
                f"  cycle ({report.cycle_mode}, {c.runs} runs): median {c.median_ms:.3f} ms, "
                f"p99 {c.p99_ms:.3f} ms ({1000.0 / c.median_ms:.0f} Hz)"
            )
        ok = ok and report.ok
    print("doctor: OK" if ok else "doctor: problems found (see above)")
    return 0 if ok else 1
