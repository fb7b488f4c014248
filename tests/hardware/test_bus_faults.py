"""What a bus fault does to a running stream, one fault at a time (OP3, Protocol 2.0; Poppy,
Protocol 1.0), through the real SDK on the simulated buses. The outcome of each is the
README's bus-fault table: recovered by a retry, or a clear error with the torque off — never a
hang, never a goal outside the limits."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from robot_retarget.errors import CommunicationError, HardwareError, ServoFaultError
from robot_retarget.hardware.bus import DynamixelBus, PortUnavailableError
from robot_retarget.hardware.dynamixel_backend import DynamixelBackend
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.dxl_bus import SimulatedBus

MakeBuses = Callable[..., dict[str, DynamixelBus]]
CYCLES = 40


def _inject(sim: SimulatedBus, fault: str, first_id: int) -> None:
    f = sim.faults
    if fault == "one dropped reply":
        f.drop_replies = 1
    elif fault == "dropped replies past the retries":
        f.drop_replies = 10_000
    elif fault == "CRC error":
        f.corrupt_replies = 1
    elif fault == "late reply":
        f.late_replies, f.late_reply_s = 1, 0.05
    elif fault == "line noise":
        f.noise_replies = 1
    elif fault == "overload bit":
        sim.servos[first_id].inject_hardware_error(0x20)  # overload (both protocols' bit 5)
    elif fault == "unplugged":
        sim.unplug()


def _stream(config: RobotConfig, sims: dict[str, SimulatedBus], make_buses: MakeBuses,
            fault: str) -> tuple[str, DynamixelBackend, dict[str, DynamixelBus]]:  # fmt: skip
    """Stream CYCLES send + read cycles, the fault injected halfway; the outcome's name."""
    buses = make_buses(config, sims)
    backend = DynamixelBackend(config, buses, handle_signals=False)
    backend.connect()
    first = config.joints[0]
    sim = sims[first.bus]
    q = config.init_pose
    try:
        for k in range(CYCLES):
            if k == CYCLES // 2:
                _inject(sim, fault, first.servo_id)
            backend.send(JointCommand(q, k * 0.01))
            backend.read_state()
    except ServoFaultError:
        return "ServoFaultError", backend, buses
    except PortUnavailableError:
        return "PortUnavailableError", backend, buses
    except CommunicationError:
        return "CommunicationError", backend, buses
    finally:
        if backend.connected:
            backend.disconnect()
    return "recovered", backend, buses


EXPECTED = {
    "one dropped reply": "recovered",
    "dropped replies past the retries": "CommunicationError",
    "CRC error": "recovered",
    "late reply": "recovered",
    "line noise": "recovered",
    "overload bit": "ServoFaultError",
    "unplugged": "PortUnavailableError",
}


@pytest.mark.parametrize("robot", ["op3", "poppy"])
@pytest.mark.parametrize("fault", list(EXPECTED))
def test_each_fault_is_recovered_or_stops_with_the_torque_off(
    robot: str, fault: str, request: pytest.FixtureRequest, make_buses: MakeBuses
) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    sims: dict[str, SimulatedBus] = request.getfixturevalue(f"{robot}_sim")
    outcome, backend, buses = _stream(config, sims, make_buses, fault)
    assert outcome == EXPECTED[fault], (fault, outcome)
    assert not backend.connected
    retries = sum(b.stats.retries for b in buses.values())
    if outcome == "recovered":
        assert retries >= 1  # each recovered fault cost exactly a retried transaction
    if fault != "unplugged":  # an unplugged servo cannot be asked; all others are off
        for sim in sims.values():
            sim.settle()
            assert not any(s.torque_on for s in sim.servos.values()), (fault, outcome)
    for sim in sims.values():  # whatever happened, no goal outside the servo's limits
        for s in sim.servos.values():
            lo, hi = s._position_limits()
            assert lo <= s.get("goal_position") <= hi


def test_a_fault_never_becomes_a_hang(op3: RobotConfig, op3_sim: dict[str, SimulatedBus],
                                      make_buses: MakeBuses) -> None:  # fmt: skip
    """Replies that never come: the error arrives after the retries, not never."""
    sim = op3_sim["main"]
    buses = make_buses(op3, op3_sim, retries=1)
    backend = DynamixelBackend(op3, buses, handle_signals=False)
    backend.connect()
    sim.faults.drop_replies = 10_000
    with pytest.raises(HardwareError):
        backend.read_state()
    assert not backend.connected or not backend.torque_on
    assert sum(b.stats.retries for b in buses.values()) >= 1
