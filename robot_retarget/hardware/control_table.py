"""Control tables of the Dynamixel models the robot configs use, as named registers.

Addresses, sizes, access and factory defaults from the ROBOTIS e-Manual pages
(emanual.robotis.com/docs/en/dxl/x/xm430-w350/ for the Protocol 2.0 XM430-W350 table;
…/dxl/mx/mx-28/, …/dxl/mx/mx-64/ (Protocol 1.0 firmware) and …/dxl/ax/ax-12a/ for the
Protocol 1.0 tables). The backend talks in register names; the simulated bus builds its servo
memory from the same tables. Units of the values we convert live next to them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from robot_retarget.robot.servo_models import RPM_TO_RAD_S


@dataclass(frozen=True)
class Register:
    name: str
    address: int
    size: int  # bytes: 1, 2 or 4
    writable: bool
    eeprom: bool  # EEPROM area: writable only while torque is off
    default: int = 0
    signed: bool = False


@dataclass(frozen=True)
class ControlTable:
    model: str
    protocol: float
    memory_size: int
    registers: Mapping[str, Register]
    # Unit of Present Velocity / Moving Speed / Profile Velocity, rad/s per LSB.
    velocity_unit_rad_s: float
    # Present load scaling: the register value that means "full load" (fraction 1.0).
    full_load: int
    # Protocol 1.0 speed/load registers are sign-magnitude with the sign in bit 10.
    sign_magnitude_bit: int | None
    fast_sync_read: bool  # Protocol 2.0 Fast Sync Read (0x8A) supported ...
    fast_sync_read_min_firmware: int  # ... from this firmware version on
    bulk_read: bool  # Bulk Read (0x92) supported

    def __getitem__(self, name: str) -> Register:
        try:
            return self.registers[name]
        except KeyError:
            raise KeyError(
                f"{self.model} has no register {name!r}; registers: {', '.join(self.registers)}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.registers

    def block(self, first: str, last: str) -> tuple[int, int]:
        """(start address, length) of the contiguous span from register ``first`` to ``last``."""
        a, b = self[first], self[last]
        return a.address, b.address + b.size - a.address


def _table(
    *regs: tuple[str, int, int, str, int] | tuple[str, int, int, str, int, bool],
) -> dict[str, Register]:
    out: dict[str, Register] = {}
    for r in regs:
        name, addr, size, access, default = r[:5]
        signed = bool(r[5]) if len(r) > 5 else False
        out[name] = Register(
            name, addr, size, "W" in access, access.startswith("E"), default, signed
        )
    return out


# XM430 Indirect Address / Data: two blocks of 28; Indirect Address k (2 bytes, default: its own
# Indirect Data k) names the register byte that Indirect Data k (1 byte) reads and writes.
XM430_INDIRECT_BLOCKS = ((168, 224), (578, 634))  # (first address register, first data byte)
XM430_INDIRECT_PER_BLOCK = 28


def _xm430_indirect() -> tuple[tuple[str, int, int, str, int], ...]:
    regs: list[tuple[str, int, int, str, int]] = []
    for block, (addr0, data0) in enumerate(XM430_INDIRECT_BLOCKS):
        for i in range(XM430_INDIRECT_PER_BLOCK):
            k = block * XM430_INDIRECT_PER_BLOCK + i + 1
            regs.append((f"indirect_address_{k}", addr0 + 2 * i, 2, "RW", data0 + i))
            regs.append((f"indirect_data_{k}", data0 + i, 1, "RW", 0))
    return tuple(regs)


# XM430-W350, Protocol 2.0. Access: "E…" EEPROM, "R…" RAM; "W" writable. EEPROM is 0–63.
XM430_W350 = ControlTable(
    model="XM430-W350",
    protocol=2.0,
    memory_size=661 + 1,
    registers=_table(
        ("model_number", 0, 2, "E", 1020),
        ("model_information", 2, 4, "E", 0),
        ("firmware_version", 6, 1, "E", 46),
        ("id", 7, 1, "EW", 1),
        ("baud_rate", 8, 1, "EW", 1),
        ("return_delay_time", 9, 1, "EW", 250),  # 2 µs per LSB
        ("drive_mode", 10, 1, "EW", 0),
        ("operating_mode", 11, 1, "EW", 3),  # 3 = position control, 4 = extended position
        ("secondary_id", 12, 1, "EW", 255),
        ("protocol_type", 13, 1, "EW", 2),
        ("homing_offset", 20, 4, "EW", 0, True),
        ("moving_threshold", 24, 4, "EW", 10),
        ("temperature_limit", 31, 1, "EW", 80),
        ("max_voltage_limit", 32, 2, "EW", 160),
        ("min_voltage_limit", 34, 2, "EW", 95),
        ("pwm_limit", 36, 2, "EW", 885),
        ("current_limit", 38, 2, "EW", 1193),
        ("velocity_limit", 44, 4, "EW", 200),
        ("max_position_limit", 48, 4, "EW", 4095),
        ("min_position_limit", 52, 4, "EW", 0),
        ("startup_configuration", 60, 1, "EW", 0),
        ("shutdown", 63, 1, "EW", 52),
        ("torque_enable", 64, 1, "RW", 0),
        ("led", 65, 1, "RW", 0),
        ("status_return_level", 68, 1, "RW", 2),
        ("registered_instruction", 69, 1, "R", 0),
        ("hardware_error_status", 70, 1, "R", 0),
        ("velocity_i_gain", 76, 2, "RW", 1920),
        ("velocity_p_gain", 78, 2, "RW", 100),
        ("position_d_gain", 80, 2, "RW", 0),
        ("position_i_gain", 82, 2, "RW", 0),
        ("position_p_gain", 84, 2, "RW", 800),
        ("feedforward_2nd_gain", 88, 2, "RW", 0),
        ("feedforward_1st_gain", 90, 2, "RW", 0),
        ("bus_watchdog", 98, 1, "RW", 0),
        ("goal_pwm", 100, 2, "RW", 885, True),
        ("goal_current", 102, 2, "RW", 1193, True),
        ("goal_velocity", 104, 4, "RW", 0, True),
        ("profile_acceleration", 108, 4, "RW", 0),  # 214.577 rev/min² per LSB
        ("profile_velocity", 112, 4, "RW", 0),  # 0.229 rpm per LSB, 0 = unlimited
        ("goal_position", 116, 4, "RW", 2048, True),
        ("realtime_tick", 120, 2, "R", 0),
        ("moving", 122, 1, "R", 0),
        ("moving_status", 123, 1, "R", 0),
        ("present_pwm", 124, 2, "R", 0, True),
        ("present_load", 126, 2, "R", 0, True),  # Present Current on XM430, 2.69 mA per LSB
        ("present_velocity", 128, 4, "R", 0, True),
        ("present_position", 132, 4, "R", 2048, True),
        ("velocity_trajectory", 136, 4, "R", 0, True),
        ("position_trajectory", 140, 4, "R", 0, True),
        ("present_input_voltage", 144, 2, "R", 120),  # 0.1 V per LSB
        ("present_temperature", 146, 1, "R", 30),  # °C
        ("backup_ready", 147, 1, "R", 0),
        *_xm430_indirect(),
    ),
    velocity_unit_rad_s=0.229 * RPM_TO_RAD_S,
    full_load=1193,  # Present Current relative to the default Current Limit (≈ 3.2 A)
    sign_magnitude_bit=None,
    fast_sync_read=True,
    fast_sync_read_min_firmware=45,  # e-Manual: Fast Sync Read from firmware v45
    bulk_read=True,
)


def _p1_table(
    model: str,
    model_number: int,
    ccw_limit: int,
    extra: tuple[tuple[str, int, int, str, int], ...],
    speed_unit_rpm: float,
    bulk_read: bool,
) -> ControlTable:
    common: tuple[tuple[str, int, int, str, int], ...] = (
        ("model_number", 0, 2, "E", model_number),
        ("firmware_version", 2, 1, "E", 0),
        ("id", 3, 1, "EW", 1),
        ("baud_rate", 4, 1, "EW", 34 if ccw_limit == 4095 else 1),
        ("return_delay_time", 5, 1, "EW", 250),  # 2 µs per LSB
        ("cw_angle_limit", 6, 2, "EW", 0),
        ("ccw_angle_limit", 8, 2, "EW", ccw_limit),
        ("temperature_limit", 11, 1, "EW", 80 if ccw_limit == 4095 else 70),
        ("min_voltage_limit", 12, 1, "EW", 60),
        ("max_voltage_limit", 13, 1, "EW", 160 if ccw_limit == 4095 else 140),
        ("max_torque", 14, 2, "EW", 1023),
        ("status_return_level", 16, 1, "EW", 2),
        ("alarm_led", 17, 1, "EW", 36),
        ("shutdown", 18, 1, "EW", 36),
        ("torque_enable", 24, 1, "RW", 0),
        ("led", 25, 1, "RW", 0),
        ("goal_position", 30, 2, "RW", ccw_limit // 2 + 1),
        ("moving_speed", 32, 2, "RW", 0),  # speed unit per LSB, 0 = maximum
        ("torque_limit", 34, 2, "RW", 1023),
        ("present_position", 36, 2, "R", ccw_limit // 2 + 1),
        ("present_speed", 38, 2, "R", 0),  # sign-magnitude, bit 10 = direction
        ("present_load", 40, 2, "R", 0),  # sign-magnitude, 0.1 % per LSB of max torque
        ("present_voltage", 42, 1, "R", 120),  # 0.1 V per LSB
        ("present_temperature", 43, 1, "R", 30),  # °C
        ("registered", 44, 1, "R", 0),
        ("moving", 46, 1, "R", 0),
        ("lock", 47, 1, "RW", 0),
        ("punch", 48, 2, "RW", 32),
    )
    return ControlTable(
        model=model,
        protocol=1.0,
        memory_size=74,
        registers=_table(*common, *extra),
        velocity_unit_rad_s=speed_unit_rpm * RPM_TO_RAD_S,
        full_load=1023,
        sign_magnitude_bit=10,
        fast_sync_read=False,
        fast_sync_read_min_firmware=0,
        bulk_read=bulk_read,
    )


_MX_EXTRA: tuple[tuple[str, int, int, str, int], ...] = (
    ("multi_turn_offset", 20, 2, "EW", 0),
    ("resolution_divider", 22, 1, "EW", 1),
    ("d_gain", 26, 1, "RW", 0),
    ("i_gain", 27, 1, "RW", 0),
    ("p_gain", 28, 1, "RW", 32),
    ("goal_acceleration", 73, 1, "RW", 0),  # 8.583 °/s² per LSB
)

MX_28 = _p1_table("MX-28", 29, 4095, _MX_EXTRA, 0.114, bulk_read=True)
MX_64 = _p1_table(
    "MX-64",
    310,
    4095,
    (
        *_MX_EXTRA,
        ("current", 68, 2, "RW", 2048),
        ("torque_control_mode_enable", 70, 1, "RW", 0),
        ("goal_torque", 71, 2, "RW", 0),
    ),
    0.114,
    bulk_read=True,
)
AX_12A = _p1_table(
    "AX-12A",
    12,
    1023,
    (
        ("cw_compliance_margin", 26, 1, "RW", 1),
        ("ccw_compliance_margin", 27, 1, "RW", 1),
        ("cw_compliance_slope", 28, 1, "RW", 32),
        ("ccw_compliance_slope", 29, 1, "RW", 32),
    ),
    0.111,
    bulk_read=False,  # the AX series has no Bulk Read instruction
)

CONTROL_TABLES: dict[str, ControlTable] = {t.model: t for t in (XM430_W350, MX_28, MX_64, AX_12A)}

# Hardware error bits → names. Protocol 2.0: register Hardware Error Status (70).
# Protocol 1.0: the status packet's error byte.
HARDWARE_ERROR_BITS_V2: dict[int, str] = {
    0x01: "input voltage",
    0x04: "overheating",
    0x08: "motor encoder",
    0x10: "electrical shock",
    0x20: "overload",
}
HARDWARE_ERROR_BITS_V1: dict[int, str] = {
    0x01: "input voltage",
    0x04: "overheating",
    0x20: "overload",
}


def error_bit_names(bits: int, protocol: float) -> tuple[str, ...]:
    """Names of the hardware error bits set in ``bits``."""
    table = HARDWARE_ERROR_BITS_V2 if protocol == 2.0 else HARDWARE_ERROR_BITS_V1
    return tuple(name for bit, name in table.items() if bits & bit)


def control_table(model: str) -> ControlTable:
    """The table of a servo model (names as in robot_retarget.robot.servo_models)."""
    try:
        return CONTROL_TABLES[model]
    except KeyError:
        raise KeyError(
            f"no control table for servo model {model!r}; known: {', '.join(CONTROL_TABLES)}"
        ) from None


def decode_sign_magnitude(value: int, sign_bit: int) -> int:
    """Protocol 1.0 speed/load: magnitude in the low bits, direction (CW = negative) in sign_bit."""
    magnitude = value & ((1 << sign_bit) - 1)
    return -magnitude if value & (1 << sign_bit) else magnitude
