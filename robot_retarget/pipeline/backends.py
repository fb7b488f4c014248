"""Backends by name for the CLI: ``sim`` (kinematic simulator) or ``dynamixel`` (a real bus).

``ports`` for Dynamixel: ``["/dev/ttyUSB0"]`` for a one-bus robot, or ``["upper=/dev/ttyUSB0",
"lower=/dev/ttyUSB1"]`` naming the config's buses. Signal handling stays with the control loop
(it stops smoothly on Ctrl-C), so the backend's own SIGINT handler is not installed.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.backend import JointBackend
from robot_retarget.robot.config import RobotConfig

BACKENDS: tuple[str, ...] = ("sim", "dynamixel")


def parse_ports(
    config: RobotConfig, ports: Sequence[str], *, all_buses: bool = True
) -> dict[str, str]:
    """``PATH`` (one-bus robots) or ``BUS=PATH`` items → {bus name: port}; two buses on one
    port are refused (``all_buses``: every bus opens, a bus not named at its default port, as
    streaming does; else only those named, one after another, as ``doctor`` checks them)."""
    names = [b.name for b in config.buses]
    out: dict[str, str] = {}
    for item in ports:
        if "=" in item:
            bus, path = item.split("=", 1)
            if bus not in names:
                raise HardwareError(
                    f"--port {item}: robot {config.name} has no bus {bus!r}; buses: {names}"
                )
        elif len(names) == 1:
            bus, path = names[0], item
        else:
            raise HardwareError(
                f"robot {config.name} has {len(names)} buses {names}: give --port BUS=PATH"
            )
        if bus in out:
            raise HardwareError(
                f"--port {item}: bus {bus!r} was given a port already ({out[bus]}); one --port "
                "per bus"
            )
        out[bus] = path
    # Two buses on one serial line would open it twice (Linux allows that): their packets,
    # at each bus's own baud rate and protocol, would interleave on the wire.
    resolved: dict[str, str] = {}
    for bus_cfg in config.buses:
        if not all_buses and bus_cfg.name not in out:
            continue
        path = out.get(bus_cfg.name, bus_cfg.default_port)
        key = os.path.realpath(path)
        if key in resolved:
            raise HardwareError(
                f"buses {resolved[key]!r} and {bus_cfg.name!r} would both open {path}: each "
                "bus is its own serial adapter; give each its own --port BUS=PATH"
            )
        resolved[key] = bus_cfg.name
    return out


def default_port_hint(config: RobotConfig, bus_name: str) -> str:
    """What to tell the user when the port of a bus no ``--port`` named cannot be opened: it is
    the config's ``default_port``, and how to give another."""
    bus = next(b for b in config.buses if b.name == bus_name)
    option = "--port PATH" if len(config.buses) == 1 else f"--port {bus_name}=PATH"
    return (
        f"{bus.default_port} is the robot config's default port for bus {bus_name} (no --port "
        f"named it): give {option}"
    )


def open_backend(
    config: RobotConfig, kind: str, ports: Sequence[str] = (), *, fix_registers: bool = False
) -> JointBackend:
    """An unconnected backend (the control loop connects it behind its safety layer);
    ``fix_registers``: a Dynamixel backend writes the EEPROM values the config expects instead
    of refusing to connect (robot_retarget.hardware.servo_registers)."""
    if kind == "sim":
        from robot_retarget.sim.backend import SimBackend

        return SimBackend(config)
    if kind == "dynamixel":
        from robot_retarget.hardware.bus import buses_from_config
        from robot_retarget.hardware.dynamixel_backend import DynamixelBackend

        given = parse_ports(config, ports)
        buses = buses_from_config(config, given)
        for name, bus in buses.items():
            if name not in given:
                bus.port_hint = default_port_hint(config, name)
        return DynamixelBackend(config, buses, handle_signals=False, fix_registers=fix_registers)
    raise HardwareError(f"unknown backend {kind!r}; choose one of {', '.join(BACKENDS)}")
