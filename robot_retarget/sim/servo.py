"""One simulated Dynamixel servo: its control-table memory, access rules and motion.

Memory is built from robot_retarget.hardware.control_table. Writes are checked like the real
firmware does: read-only registers → access error, EEPROM while torque is on → access error,
a goal position outside the position limits → data limit error (value ignored). Present
position/velocity follow the goal through :class:`robot_retarget.sim.kinematic.ServoDynamics`
whenever torque is on, advanced lazily to the bus's clock when the servo is touched.

As the e-Manuals describe: on Protocol 2.0 models (XM430) Present and Goal Position are in the
user's frame, so a servo calibrated by another tool really does put its horn elsewhere:

    Present Position = mirror(horn) + Homing Offset,  mirror(t) = 4096 − t if reverse else t

"Present Position = Actual Position + Homing Offset" is the XM430 e-Manual's formula; Drive
Mode bit 0 (reverse) inverts the direction of Goal and Present Position, read here as the
horn's angle negated (−t modulo one turn: 4096 − t, so the centre 2048 stays 2048), and "the
sign of Homing Offset is not reversed" in reverse mode. A goal is taken back through the same
map. In Position Control Mode (single turn) a Homing Offset outside ±1024 is ignored, as the
e-Manual states. Min/Max Position Limit and CW/CCW Angle Limit bound Goal Position in that user
frame: a goal outside them is refused (Protocol 1.0: the Angle Limit error bit; Protocol 2.0:
Data Limit Error) and the servo keeps its previous goal, which under Sync Write (no status
packet) nobody hears about. The EEPROM area is locked while torque is on on Protocol 2.0
models only (the XM430 e-Manual's rule; the AX-12A and MX Protocol 1.0 pages have none, and
pypot writes angle limits to servos holding torque). On Protocol 1.0 models (MX, AX) Lock = 1
makes the EEPROM area read-only, and Lock itself cannot be cleared, until the servo is powered
off (a new SimServo). After a hardware-error shutdown a Protocol 2.0 servo keeps its torque off
until rebooted ("REBOOT is the only method to reset Torque Enable to 1"). A reboot
re-initialises the RAM area; a factory reset the EEPROM area too (ID and baud rate kept as the
instruction's parameter says). With Drive Mode reverse, Present Velocity turns with Present
Position.
"""

from __future__ import annotations

import math

from robot_retarget.hardware.control_table import (
    XM430_INDIRECT_BLOCKS,
    XM430_INDIRECT_PER_BLOCK,
    ControlTable,
    Register,
    control_table,
)
from robot_retarget.hardware.protocol import le_bytes
from robot_retarget.robot.servo_models import servo_model
from robot_retarget.sim.kinematic import ServoDynamics

# Status-packet error codes the servo can produce, protocol-neutral.
OK = 0
ACCESS_ERROR = 1
DATA_LIMIT_ERROR = 2
DATA_LENGTH_ERROR = 3
RESULT_FAIL = 4  # Protocol 2.0 "Result Fail": the instruction could not be carried out
DATA_RANGE_ERROR = 5  # a value the register does not take (Protocol 2.0 error 0x04)

_POSITION_MODE = 3  # XM430 Operating Mode: position control within one turn
_EXTENDED_POSITION_MODE = 4
_VELOCITY_MODE = 1
_CURRENT_BASED_POSITION_MODE = 5  # position over many turns, the current limited
_MAX_SINGLE_TURN_HOMING = 1024  # valid Homing Offset range in Position Control Mode
_MULTI_TURN_GOAL = 1_048_575  # XM430 Goal Position range in modes 4 and 5
# Registers the servo itself keeps writing; any other changes its mode, limits or frame.
_STATE_REGISTERS = frozenset(
    ("present_position", "present_velocity", "present_speed", "moving", "goal_position",
     "hardware_error_status", "registered", "registered_instruction", "torque_enable")
)  # fmt: skip
_INDIRECT_TARGETS = (64, 661)  # what an XM430 Indirect Address may name
_MX_MULTI_TURN_GOAL = 28_672  # MX (Protocol 1.0) Goal Position range in multi-turn mode
# Values a register takes (e-Manual); anything else is a Data Range Error.
_VALUES_V2: dict[str, frozenset[int]] = {
    "operating_mode": frozenset((0, 1, 3, 4, 5, 16)),
    "torque_enable": frozenset((0, 1)),
    "led": frozenset((0, 1)),
    "status_return_level": frozenset((0, 1, 2)),
    "id": frozenset(range(253)),
    "baud_rate": frozenset(range(8)),
}
_VALUES_V1: dict[str, frozenset[int]] = {
    "torque_enable": frozenset((0, 1)),
    "led": frozenset((0, 1)),
    "status_return_level": frozenset((0, 1, 2)),
    "id": frozenset(range(254)),
}
# Protocol 2.0 goals bounded by a limit register: |goal| ≤ limit, else a Data Limit Error.
_GOAL_LIMITS = {"goal_velocity": "velocity_limit", "goal_current": "current_limit",
                "goal_pwm": "pwm_limit"}  # fmt: skip


class SimServo:
    """A servo on the simulated bus. ``hardware_error`` holds injected fault bits (Protocol 2.0:
    Hardware Error Status; Protocol 1.0: status error bits)."""

    def __init__(self, servo_id: int, model: str, *, time_constant_s: float = 0.01) -> None:
        self.model = servo_model(model)
        self.table: ControlTable = control_table(model)
        self.protocol = self.table.protocol
        self.memory = bytearray(self.table.memory_size)
        self._frame: tuple[str, bool, int, tuple[int, int]] | None = None
        self._by_address: dict[int, Register] = {}
        self._owner: list[Register | None] = [None] * len(self.memory)  # each byte's register
        for reg in self.table.registers.values():
            self._by_address[reg.address] = reg
            self._owner[reg.address : reg.address + reg.size] = [reg] * reg.size
            self.memory[reg.address : reg.address + reg.size] = le_bytes(reg.default, reg.size)
        self._id_address = self.table["id"].address
        self._srl_address = self.table["status_return_level"].address
        self._put("id", servo_id)
        indirect = "indirect_address_1" in self.table
        self._indirect_blocks = XM430_INDIRECT_BLOCKS if indirect else ()
        self.hardware_error = 0
        self.registered: tuple[int, bytes] | None = None
        self.dynamics = ServoDynamics(
            q_rad=0.0,
            max_velocity_rad_s=self.model.no_load_speed_rad_s,
            time_constant_s=time_constant_s,
        )
        self.writes = 0  # accepted write transactions (for tests)

    @property
    def servo_id(self) -> int:
        """The ID it answers to: its ID register (a write there moves it to another ID)."""
        return self.memory[self._id_address]  # one byte on every model

    @property
    def status_return_level(self) -> int:
        """0: a status for PING only; 1: for PING and reads; 2: for every instruction."""
        return self.memory[self._srl_address]

    # ----- registers -------------------------------------------------------------------------
    def get(self, name: str) -> int:
        reg = self.table[name]
        return int.from_bytes(
            self.memory[reg.address : reg.address + reg.size], "little", signed=reg.signed
        )

    def _put(self, name: str, value: int) -> None:
        reg = self.table[name]
        self.memory[reg.address : reg.address + reg.size] = le_bytes(value, reg.size)
        if name not in _STATE_REGISTERS:
            self._frame = None

    @property
    def torque_on(self) -> bool:
        return self.get("torque_enable") != 0

    def ticks_to_rad(self, ticks: float) -> float:
        return (ticks - self.model.zero_tick) * self.model.rad_per_tick

    def rad_to_ticks(self, q_rad: float) -> int:
        return round(q_rad / self.model.rad_per_tick) + self.model.zero_tick

    def set_present_rad(self, q_rad: float) -> None:
        """Put the horn somewhere (e.g. where the robot was left): also the holding goal."""
        self.dynamics.q_rad = q_rad
        self._put("present_position", self.user_from_horn(self.rad_to_ticks(q_rad)))
        self._put("goal_position", self.user_from_horn(self.rad_to_ticks(q_rad)))

    def mode(self) -> str:
        return self._settings()[0]

    def _settings(self) -> tuple[str, bool, int, tuple[int, int]]:
        """(mode, reversed, homing offset, goal limits), read from the registers once per
        change of them: the simulated bus asks for them on every packet."""
        if self._frame is None:
            mode = self._read_mode()
            limits = self._read_position_limits(mode)
            self._frame = (mode, self._read_reversed(), self._read_homing(), limits)
        return self._frame

    def _read_mode(self) -> str:
        """How the servo moves: "position" (within its limits), "multi-turn" (XM430 modes 4
        and 5, MX with both angle limits at 4095: the position limits do not apply),
        "velocity" (XM430 mode 1: Goal Velocity), "wheel" (AX/MX with both angle limits 0:
        Moving Speed), or "torque" (XM430 current and PWM control: the horn goes where the
        load takes it, which a kinematic model cannot say, so it stays)."""
        if self.protocol == 2.0:
            mode = self.get("operating_mode")
            if mode in (_EXTENDED_POSITION_MODE, _CURRENT_BASED_POSITION_MODE):
                return "multi-turn"
            return {_POSITION_MODE: "position", _VELOCITY_MODE: "velocity"}.get(mode, "torque")
        cw, ccw = self.get("cw_angle_limit"), self.get("ccw_angle_limit")
        if cw == ccw == 0:
            return "wheel"
        if cw == ccw == self.model.max_tick and "multi_turn_offset" in self.table:
            return "multi-turn"
        return "position"

    def _position_limits(self) -> tuple[int, int]:
        return self._settings()[3]

    def _read_position_limits(self, mode: str) -> tuple[int, int]:
        if mode == "multi-turn":
            span = _MULTI_TURN_GOAL if self.protocol == 2.0 else _MX_MULTI_TURN_GOAL
            return -span, span
        if mode in ("velocity", "wheel", "torque"):
            return -(2**31), 2**31 - 1  # Goal Position is not used
        if self.protocol == 2.0:
            return self.get("min_position_limit"), self.get("max_position_limit")
        return self.get("cw_angle_limit"), self.get("ccw_angle_limit")

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        if length <= 0 or address < 0 or address + length > len(self.memory):
            return ACCESS_ERROR, b""
        end = address + length
        if not self._touches_indirect(address, end):
            return OK, bytes(self.memory[address:end])
        return OK, bytes(self.memory[self._through_indirect(a)] for a in range(address, end))

    def _touches_indirect(self, start: int, end: int) -> bool:
        return bool(self._indirect_blocks) and any(
            start < data0 + XM430_INDIRECT_PER_BLOCK and data0 < end
            for _, data0 in self._indirect_blocks
        )

    def _through_indirect(self, address: int) -> int:
        """The byte an address stands for: an Indirect Data byte's Indirect Address, else
        itself (an Indirect Address naming no byte of the table leaves the data byte alone)."""
        for addr0, data0 in self._indirect_blocks:
            k = address - data0
            if 0 <= k < XM430_INDIRECT_PER_BLOCK:
                a = addr0 + 2 * k
                target = self.memory[a] | self.memory[a + 1] << 8
                return target if target < len(self.memory) else address
        return address

    def _writable(self, reg: Register) -> bool:
        if not reg.writable:
            return False
        if reg.eeprom and self.torque_on and self.protocol == 2.0:
            return False  # EEPROM is locked while torque is on
        # Lock = 1: EEPROM read-only until power-off
        return not (self._locked() and (reg.eeprom or reg.name == "lock"))

    def write(self, address: int, data: bytes) -> int:
        """Write a byte span; all of it or nothing. Returns an error code."""
        end = address + len(data)
        if not data or address < 0 or end > len(self.memory):
            return ACCESS_ERROR
        # The registers that start inside the span, in address order (each byte's owner).
        regs = list(
            {id(r): r for r in self._owner[address:end] if r and r.address >= address}.values()
        )
        for reg in regs:
            if reg.address + reg.size > end:
                return DATA_LENGTH_ERROR  # would split a register
            if not self._writable(reg):
                return ACCESS_ERROR
        if address not in self._by_address or not regs:
            return ACCESS_ERROR
        if not self._touches_indirect(address, end):  # the common case: no copy of the memory
            for reg in regs:
                code = self._check_value(
                    reg, data[reg.address - address : reg.address - address + reg.size]
                )
                if code != OK:
                    return code
            self.memory[address:end] = data
            return self._accepted()
        new = bytearray(self.memory)
        touched = {r.address: r for r in regs}
        for a, byte in zip(range(address, end), data, strict=True):
            target = self._through_indirect(a)
            new[target] = byte
            if target != a:  # through an Indirect Data byte: the named register's rules
                owner = self._owner[target]
                if owner is None or not self._writable(owner):
                    return ACCESS_ERROR
                touched[owner.address] = owner
        return self._commit(new, list(touched.values()))

    def _commit(self, new: bytearray, touched: list[Register]) -> int:
        """Store ``new`` as the memory if every touched register takes its new value."""
        for reg in touched:
            code = self._check_value(reg, bytes(new[reg.address : reg.address + reg.size]))
            if code != OK:
                return code
        self.memory[:] = new  # a goal is stored; the horn moves only with torque on
        return self._accepted()

    def _accepted(self) -> int:
        self._frame = None  # the mode, limits or user frame may have changed
        if self.hardware_error and self.protocol == 2.0 and self.get("torque_enable"):
            self._put("torque_enable", 0)  # after a shutdown only a reboot re-enables torque
        self.writes += 1
        return OK

    def _check_value(self, reg: Register, raw: bytes) -> int:
        """OK, or the error a real servo gives for writing ``raw`` into ``reg``."""
        signed = reg.signed or (reg.name == "goal_position" and self.mode() == "multi-turn")
        value = int.from_bytes(raw, "little", signed=signed)
        if reg.name == "goal_position":
            lo, hi = self._position_limits()
            return OK if lo <= value <= hi else DATA_LIMIT_ERROR
        if reg.name.startswith("indirect_address_"):
            return OK if _INDIRECT_TARGETS[0] <= value <= _INDIRECT_TARGETS[1] else DATA_RANGE_ERROR
        if self.protocol == 2.0 and reg.name in _GOAL_LIMITS:
            return OK if abs(value) <= self.get(_GOAL_LIMITS[reg.name]) else DATA_LIMIT_ERROR
        values = (_VALUES_V2 if self.protocol == 2.0 else _VALUES_V1).get(reg.name)
        if values is not None and value not in values:
            return DATA_RANGE_ERROR
        return OK

    def _locked(self) -> bool:
        return self.protocol == 1.0 and "lock" in self.table and self.get("lock") == 1

    # User frame (registers) ↔ the horn's own ticks: reverse mirrors, Homing Offset shifts.
    def _reversed(self) -> bool:
        return self._settings()[1]

    def _homing(self) -> int:
        return self._settings()[2]

    def _read_reversed(self) -> bool:
        return "drive_mode" in self.table and bool(self.get("drive_mode") & 0x01)

    def _read_homing(self) -> int:
        if "homing_offset" not in self.table:
            return 0
        offset = self.get("homing_offset")
        # e-Manual: in (single-turn) Position Control Mode an offset outside ±1024 is ignored.
        if self.get("operating_mode") == _POSITION_MODE and abs(offset) > _MAX_SINGLE_TURN_HOMING:
            return 0
        return offset

    def user_from_horn(self, horn_ticks: int) -> int:
        raw = 2 * self.model.zero_tick - horn_ticks if self._reversed() else horn_ticks
        return raw + self._homing()

    def horn_from_user(self, user_ticks: int) -> int:
        raw = user_ticks - self._homing()
        return 2 * self.model.zero_tick - raw if self._reversed() else raw

    # ----- motion ----------------------------------------------------------------------------
    def _max_speed_rad_s(self) -> float:
        speed_reg = "profile_velocity" if self.protocol == 2.0 else "moving_speed"
        units = self.get(speed_reg) & 0x3FF if self.protocol == 1.0 else self.get(speed_reg)
        if units == 0:
            return self.model.no_load_speed_rad_s
        return min(units * self.table.velocity_unit_rad_s, self.model.no_load_speed_rad_s)

    def advance(self, dt_s: float) -> None:
        """Move for ``dt_s`` seconds and refresh the present-state registers."""
        if dt_s <= 0.0:
            return
        mode = self.mode()
        if not self.torque_on or self.hardware_error_latched or mode == "torque":
            self.dynamics.velocity_rad_s = 0.0
        elif mode in ("velocity", "wheel"):
            self._turn(self._commanded_velocity_rad_s(), dt_s)
        else:
            self.dynamics.max_velocity_rad_s = self._max_speed_rad_s()
            lo, hi = sorted(self.horn_from_user(t) for t in self._position_limits())
            self.dynamics.lower_rad = self.ticks_to_rad(lo)
            self.dynamics.upper_rad = self.ticks_to_rad(hi)
            self.dynamics.step(self.goal_rad, dt_s)
        ticks = round(self.dynamics.q_rad / self.model.rad_per_tick) + self.model.zero_tick
        if mode == "wheel":  # Protocol 1.0 Present Position stays within one turn
            ticks = min(ticks % round(2 * math.pi / self.model.rad_per_tick), self.model.max_tick)
        self._put("present_position", self.user_from_horn(ticks))
        vel_units = round(self.dynamics.velocity_rad_s / self.table.velocity_unit_rad_s)
        moving = int(abs(vel_units) > 0)
        if self.protocol == 2.0:
            # The horn's velocity in the user's frame: reverse mode turns it with the position.
            self._put("present_velocity", -vel_units if self._reversed() else vel_units)
            self._put("hardware_error_status", self.hardware_error)
        else:
            magnitude = min(abs(vel_units), 1023)
            self._put("present_speed", magnitude | (1024 if vel_units < 0 else 0))
        self._put("moving", moving)

    def clear_turns(self) -> None:
        """Clear (multi-turn): Present Position back within one turn, 0–4095; the horn stays."""
        turns = self.get("present_position") // self.model.ticks_per_range
        if turns:
            turn_rad = self.model.ticks_per_range * self.model.rad_per_tick
            self.dynamics.q_rad -= (-1.0 if self._reversed() else 1.0) * turns * turn_rad
            self.set_present_rad(self.dynamics.q_rad)

    def _commanded_velocity_rad_s(self) -> float:
        """The horn's velocity in velocity (Goal Velocity, within Velocity Limit) or wheel mode
        (Moving Speed: magnitude in bits 0–9, bit 10 set = clockwise, i.e. negative)."""
        unit = self.table.velocity_unit_rad_s
        if self.protocol == 2.0:
            limit = self.get("velocity_limit")
            user = max(-limit, min(limit, self.get("goal_velocity"))) * unit
            v = -user if self._reversed() else user
        else:
            speed = self.get("moving_speed")
            v = (speed & 0x3FF) * unit * (-1.0 if speed & 0x400 else 1.0)
        top = self.model.no_load_speed_rad_s
        return max(-top, min(top, v))

    def _turn(self, velocity_rad_s: float, dt_s: float) -> None:
        """Turn at ``velocity_rad_s`` for ``dt_s`` (no position limits: a wheel)."""
        self.dynamics.lower_rad, self.dynamics.upper_rad = -math.inf, math.inf
        self.dynamics.q_rad += velocity_rad_s * dt_s
        self.dynamics.velocity_rad_s = velocity_rad_s

    @property
    def hardware_error_latched(self) -> bool:
        return self.hardware_error != 0

    def inject_hardware_error(self, bits: int) -> None:
        """Latch fault bits; like the firmware's shutdown, torque goes off."""
        self.hardware_error = bits
        if bits:
            self._put("torque_enable", 0)
        if self.protocol == 2.0:
            self._put("hardware_error_status", bits)

    def reboot(self) -> None:
        """Clears the hardware error and re-initialises the RAM area (torque off, LED off,
        profiles and gains at their defaults); the goal is where the horn is."""
        self.hardware_error = 0
        self.registered = None  # a Reg Write does not survive a reboot
        for reg in self.table.registers.values():
            if not reg.eeprom:
                self.memory[reg.address : reg.address + reg.size] = le_bytes(reg.default, reg.size)
        self._frame = None
        self.set_present_rad(self.dynamics.q_rad)
        self.dynamics.velocity_rad_s = 0.0

    def factory_reset(self, *, keep_id: bool, keep_baud: bool) -> None:
        """Every register back to its factory default (the ID and baud rate kept if asked), as
        the Factory Reset instruction does; then a reboot."""
        kept = {
            name: self.get(name)
            for name, keep in (("id", keep_id), ("baud_rate", keep_baud))
            if keep
        }
        for reg in self.table.registers.values():
            self.memory[reg.address : reg.address + reg.size] = le_bytes(reg.default, reg.size)
        for name, value in kept.items():
            self._put(name, value)
        self.reboot()

    @property
    def goal_rad(self) -> float:
        """Where the horn goes (its own frame, after Homing Offset and Drive Mode)."""
        return self.ticks_to_rad(self.horn_from_user(self.get("goal_position")))

    @property
    def present_rad(self) -> float:
        return self.dynamics.q_rad

    def status_error_v1(self, code: int) -> int:
        """Protocol 1.0 error byte for an instruction result plus latched hardware bits."""
        bits = self.hardware_error & 0x25
        if code == DATA_LIMIT_ERROR:
            bits |= 0x02  # angle limit error
        elif code in (ACCESS_ERROR, DATA_LENGTH_ERROR, DATA_RANGE_ERROR):
            bits |= 0x08  # range error
        return bits

    def status_error_v2(self, code: int) -> int:
        """Protocol 2.0 error field: an error number and the alert bit for hardware errors."""
        number = {
            OK: 0,
            RESULT_FAIL: 0x01,
            DATA_RANGE_ERROR: 0x04,
            ACCESS_ERROR: 0x07,
            DATA_LIMIT_ERROR: 0x06,
            DATA_LENGTH_ERROR: 0x05,
        }[code]
        return number | (0x80 if self.hardware_error else 0)
