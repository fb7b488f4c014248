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


# Protocol 2.0 (X series, e-Manual "Baud Rate (8)"): a register value picks one of these.
_PROTOCOL2_BAUDS = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
# Protocol 1.0 (AX / MX, e-Manual "Baud Rate (4)"): 2 Mbps / (value + 1), value 0…254, and
# MX's 250–252 for 2.25, 2.5 and 3 Mbps; the servo tolerates a host rate 3 % off its own.
_PROTOCOL1_SPECIAL = (2_250_000, 2_500_000, 3_000_000)
_BAUD_TOLERANCE = 0.03

BAUD_RATES_TEXT = {
    2.0: ", ".join(str(b) for b in _PROTOCOL2_BAUDS),
    1.0: "2000000 / (n + 1) for n = 0…254 within 3 % (1000000, 500000, 115200, 57600, …), "
    "or 2250000, 2500000, 3000000 (MX)",
}


def baud_supported(protocol: float, baud: int) -> bool:
    """Whether servos speaking ``protocol`` can be set to ``baud`` bits per second."""
    if protocol == 2.0:
        return baud in _PROTOCOL2_BAUDS
    if baud in _PROTOCOL1_SPECIAL:
        return True
    if baud <= 0:
        return False
    n = round(2_000_000 / baud) - 1
    return 0 <= n <= 254 and abs(2_000_000 / (n + 1) - baud) <= _BAUD_TOLERANCE * baud


_PROTOCOL1_SPECIAL_FIRST_VALUE = 250  # MX: 250, 251, 252 → 2.25, 2.5, 3 Mbps


def baud_register_value(protocol: float, baud: int) -> int:
    """The Baud Rate register value that sets servos speaking ``protocol`` to ``baud``
    (ValueError where none does: see :func:`baud_supported`)."""
    if not baud_supported(protocol, baud):
        raise ValueError(f"no Protocol {protocol} baud rate register value gives {baud} bps")
    if protocol == 2.0:
        return _PROTOCOL2_BAUDS.index(baud)
    if baud in _PROTOCOL1_SPECIAL:
        return _PROTOCOL1_SPECIAL_FIRST_VALUE + _PROTOCOL1_SPECIAL.index(baud)
    return round(2_000_000 / baud) - 1


def register_baud(protocol: float, value: int) -> float | None:
    """The bit rate a Baud Rate register ``value`` sets (None: a value the servo rejects)."""
    if protocol == 2.0:
        return float(_PROTOCOL2_BAUDS[value]) if 0 <= value < len(_PROTOCOL2_BAUDS) else None
    special = value - _PROTOCOL1_SPECIAL_FIRST_VALUE
    if 0 <= special < len(_PROTOCOL1_SPECIAL):
        return float(_PROTOCOL1_SPECIAL[special])
    return 2_000_000 / (value + 1) if 0 <= value <= 254 else None


def bauds_match(host_baud: float, servo_baud: float) -> bool:
    """Whether a servo at ``servo_baud`` understands a host at ``host_baud`` (3 % apart)."""
    return abs(host_baud - servo_baud) <= _BAUD_TOLERANCE * servo_baud
