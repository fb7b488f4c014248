"""``inspect`` of a robot config (``my_robot.yaml``): is it valid, and what does it describe.

The config is read by the same loader ``convert`` and ``stream`` use, so a mistake is reported
as they would report it (file, key, what is allowed); a valid one is summarised: its buses, its
servos and their models, each joint's limits and speed, the mapped bones. A user writing their
own robot checks it here before anything moves.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

CONFIG_SUFFIXES = (".yaml", ".yml")


def is_robot_config(path: str) -> bool:
    """Whether ``path`` names a robot config file (by its suffix)."""
    return Path(path).suffix.lower() in CONFIG_SUFFIXES


def describe_robot_config(path: str) -> dict[str, Any]:
    """Facts about the robot config at ``path``, as JSON-ready values (angles in degrees)."""
    from robot_retarget.robot.loader import load_robot_config

    config = load_robot_config(path)
    return {
        "file": path,
        "kind": "robot config",
        "robot": config.name,
        "description": config.description,
        "control_rate_hz": config.control_rate_hz,
        "buses": [
            {
                "name": b.name,
                "protocol": b.protocol,
                "baud_rate": b.baud_rate,
                "default_port": b.default_port,
                "servo_ids": [j.servo_id for j in config.joints if j.bus == b.name],
            }
            for b in config.buses
        ],
        "joints": [
            {
                "name": j.name,
                "servo_id": j.servo_id,
                "model": j.servo_model,
                "bus": j.bus,
                "limits_deg": [math.degrees(j.lower_rad), math.degrees(j.upper_rad)],
                "max_velocity_deg_s": math.degrees(j.max_velocity_rad_s),
            }
            for j in config.joints
        ],
        "bones": [f"{b.canonical}: {b.start_frame} → {b.end_frame}" for b in config.bones],
    }


def format_robot_config_text(info: dict[str, Any]) -> str:
    buses = ", ".join(
        f"{b['name']} (Protocol {b['protocol']:.1f}, {b['baud_rate']} baud, {len(b['servo_ids'])} "
        f"servos, default port {b['default_port']})"
        for b in info["buses"]
    )
    lines = [
        f"{info['file']}",
        f"  kind:        robot config, valid ({info['robot']}: {info['description']})",
        f"  control:     {info['control_rate_hz']:g} Hz",
        f"  buses:       {buses}",
        f"  joints:      {len(info['joints'])}; bones mapped: {len(info['bones'])}",
    ]
    for j in info["joints"]:
        lo, hi = j["limits_deg"]
        lines.append(
            f"    {j['name']:<16} id {j['servo_id']:>3} {j['model']:<11} on {j['bus']:<10} "
            f"{lo:7.1f}° … {hi:6.1f}°, {j['max_velocity_deg_s']:.0f}°/s"
        )
    return "\n".join(lines)
