"""Dynamixel servo models used by the robot configs: resolution, zero, range, speed, model number.

Numbers from the ROBOTIS e-Manuals (emanual.robotis.com) for each model:
position resolution and centre, the position range, the no-load speed at the nominal voltage
and the model number the servo reports to a ping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class ServoModel:
    """Static facts about one Dynamixel model."""

    name: str
    model_number: int
    protocols: tuple[float, ...]
    ticks_per_range: int  # number of position ticks over ``range_rad``
    range_rad: float  # mechanical/encoder range covered by ticks 0 … ticks_per_range − 1
    zero_tick: int  # tick value at 0 rad (the horn's centre)
    no_load_speed_rad_s: float  # at the nominal voltage below
    nominal_voltage_v: float

    @property
    def rad_per_tick(self) -> float:
        return self.range_rad / self.ticks_per_range

    @property
    def min_tick(self) -> int:
        return 0

    @property
    def max_tick(self) -> int:
        return self.ticks_per_range - 1


SERVO_MODELS: dict[str, ServoModel] = {
    # XM430-W350-T/R: 0–4095 over 360°, 2048 centre; 46 rpm no-load at 12.0 V; model no. 1020.
    "XM430-W350": ServoModel(
        "XM430-W350", 1020, (2.0,), 4096, 2.0 * math.pi, 2048, 46.0 * RPM_TO_RAD_S, 12.0
    ),
    # MX-28 (Protocol 1.0 firmware): 0–4095 over 360°, 2048 centre; 55 rpm at 12 V; model no. 29.
    "MX-28": ServoModel("MX-28", 29, (1.0,), 4096, 2.0 * math.pi, 2048, 55.0 * RPM_TO_RAD_S, 12.0),
    # MX-64 (Protocol 1.0 firmware): 0–4095 over 360°, 2048 centre; 63 rpm at 12 V; model no. 310.
    "MX-64": ServoModel("MX-64", 310, (1.0,), 4096, 2.0 * math.pi, 2048, 63.0 * RPM_TO_RAD_S, 12.0),
    # AX-12A: 0–1023 over 300°, 512 centre; 59 rpm at 12 V; model no. 12.
    "AX-12A": ServoModel(
        "AX-12A", 12, (1.0,), 1024, math.radians(300.0), 512, 59.0 * RPM_TO_RAD_S, 12.0
    ),
}


def servo_model(name: str) -> ServoModel:
    """Look up a model by name; KeyError lists the known ones."""
    try:
        return SERVO_MODELS[name]
    except KeyError:
        raise KeyError(
            f"unknown servo model {name!r}; known models: {', '.join(sorted(SERVO_MODELS))}"
        ) from None
