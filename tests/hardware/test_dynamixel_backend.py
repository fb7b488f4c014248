"""DynamixelBackend end to end: the real dynamixel-sdk + pyserial against the simulated bus."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable

import numpy as np
import pytest

from robot_retarget.errors import CommunicationError, HardwareError, ServoFaultError
from robot_retarget.hardware import protocol as p
from robot_retarget.hardware.bus import DynamixelBus
from robot_retarget.hardware.dynamixel_backend import (
    BACKEND_BUDGET_PERIODS,
    DynamixelBackend,
    ModelMismatchError,
    NotConnectedError,
)
from robot_retarget.hardware.safety import SafetyLayer, UnsafeCommandError
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.servo_units import ServoUnits
from robot_retarget.sim.dxl_bus import SimulatedBus
from tests.pipeline.scripted import FakeClock

MakeBuses = Callable[..., dict[str, DynamixelBus]]
FRAMES = 2000
RATE_HZ = 500.0  # fast to keep the suite short; the check is that ≥ 100 Hz is reached


def _servo(sims: dict[str, SimulatedBus], config: RobotConfig, i: int):  # type: ignore[no-untyped-def]
    j = config.joints[i]
    return sims[j.bus].servos[j.servo_id]


def _trajectory(config: RobotConfig, k: int, rate_hz: float) -> np.ndarray:
    """Smooth motion around the init pose, inside the limits, ≤ 1 rad/s."""
    t = k / rate_hz
    phase = np.arange(config.num_joints) * 0.4
    q = config.init_pose + 0.25 * np.sin(2 * np.pi * 0.5 * t + phase) * np.sin(
        np.pi * min(t, 1.0) / 2
    )
    return np.clip(q, config.lower + 0.05, config.upper - 0.05)


def _settle(sims: dict[str, SimulatedBus]) -> None:
    for s in sims.values():
        s.settle()


def _stream(config: RobotConfig, sims: dict[str, SimulatedBus], make_buses: MakeBuses) -> None:
    backend = DynamixelBackend(config, make_buses(config, sims))
    q_cmd = np.zeros(0)
    errors = []
    with backend:
        assert not any(s.torque_on for b in sims.values() for s in b.servos.values())
        t0 = time.perf_counter()
        for k in range(FRAMES):
            q_cmd = _trajectory(config, k, RATE_HZ)
            sent = backend.send(JointCommand(q_cmd, k / RATE_HZ))
            state = backend.read_state()
            errors.append(np.max(np.abs(state.q - sent.q)))
            wait = t0 + (k + 1) / RATE_HZ - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
        assert backend.torque_on
        _settle(sims)
        # Every servo holds exactly the last goal (to the tick) ...
        ticks = ServoUnits(config).to_ticks(q_cmd)
        for i in range(config.num_joints):
            assert _servo(sims, config, i).get("goal_position") == ticks[i]
        # ... tracked it while streaming (lag of a smooth ≤ 1 rad/s motion) ...
        assert np.median(errors) < 0.03
        assert np.max(errors[100:]) < 0.2
        # ... and the read back state agrees with the simulated horns after settling.
        time.sleep(0.1)
        state = backend.read_state()
        np.testing.assert_allclose(state.q, ServoUnits(config).from_ticks(ticks), atol=0.01)
    _settle(sims)
    assert not any(s.torque_on for b in sims.values() for s in b.servos.values())


def test_op3_streams_2000_frames(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    _stream(op3, op3_sim, make_buses)
    sim = next(iter(op3_sim.values()))
    for s in sim.servos.values():
        assert s.get("return_delay_time") == 0
        assert s.get("operating_mode") == 3
    assert not sim.log.rejected


def test_poppy_streams_2000_frames_on_two_buses(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    assert len(poppy.buses) == 2
    _stream(poppy, poppy_sim, make_buses)
    for sim in poppy_sim.values():
        assert not sim.log.rejected
        inst = {raw[4] for raw in list(sim.log.packets)}
        assert p.INST_BULK_READ in inst
        assert p.INST_SYNC_WRITE in inst


def test_model_mismatch_names_id_expected_and_found(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    j = op3.joints[4]
    servo = op3_sim[j.bus].servos[j.servo_id]
    servo._put("model_number", 1200)  # an XL430-W250 where an XM430 should be
    with pytest.raises(ModelMismatchError) as info:
        DynamixelBackend(op3, make_buses(op3, op3_sim)).connect()
    assert (info.value.servo_id, info.value.expected, info.value.found) == (j.servo_id, 1020, 1200)
    assert "1200" in str(info.value)
    assert str(j.servo_id) in str(info.value)


def test_missing_servo_fails_connect(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    j = op3.joints[0]
    del op3_sim[j.bus].servos[j.servo_id]
    with pytest.raises(CommunicationError, match=f"ID {j.servo_id}"):
        DynamixelBackend(op3, make_buses(op3, op3_sim)).connect()


def _goals_on_wire(sim: SimulatedBus, servo_id: int, reg_addr: int) -> list[int]:
    """Every goal the bus received for ``servo_id`` in Sync Writes (Protocol 2.0)."""
    out = []
    for raw in list(sim.log.packets):  # a snapshot: the bus thread appends
        pkt = p.parse_v2(raw)
        if pkt.code != p.INST_SYNC_WRITE or p.from_le(pkt.params[:2]) != reg_addr:
            continue
        size = p.from_le(pkt.params[2:4])
        body = pkt.params[4:]
        for k in range(0, len(body), size + 1):
            if body[k] == servo_id:
                out.append(p.from_le(body[k + 1 : k + 1 + size], signed=True))
    return out


def test_torque_on_only_with_a_velocity_limited_move(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    j = op3.joints[0]
    target = op3.init_pose.copy()
    target[0] = np.clip(target[0] + 0.5, op3.lower[0], op3.upper[0])
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), ramp_speed_fraction=1.0)
    with backend:
        backend.send(JointCommand(target, 0.0))
        _settle(op3_sim)
        goals = _goals_on_wire(sim, j.servo_id, 116)
    present_tick = ServoUnits(op3).to_ticks(op3.init_pose)[0]
    assert goals[0] == present_tick  # goal := present before torque on
    max_step_ticks = op3.max_velocity[0] / op3.control_rate_hz / (2 * np.pi / 4096) + 1
    assert np.max(np.abs(np.diff(goals))) <= max_step_ticks
    assert len(goals) > 5
    # torque enable came after the hold-position goal
    order = [
        p.parse_v2(r).params[:2]
        for r in list(sim.log.packets)
        if p.parse_v2(r).code == p.INST_SYNC_WRITE
    ]
    assert order.index(p.le_bytes(64, 2)) > order.index(p.le_bytes(116, 2))


def test_a_ramp_that_falls_behind_does_not_send_its_late_steps_at_once(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    """The torque-on move on a busy machine: one of its sleeps lasts ten periods. The steps
    after it still come a period apart (before, the eight it was late for went out back to
    back, and the servo saw one jump of eight steps)."""
    period = 1.0 / op3.control_rate_hz
    naps: list[float] = []

    def busy_sleep(dt_s: float) -> None:
        naps.append(dt_s)
        time.sleep(dt_s + (10 * period if len(naps) == 3 else 0.0))

    target = op3.init_pose.copy()
    target[0] = np.clip(target[0] + 0.5, op3.lower[0], op3.upper[0])
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim), sleep=busy_sleep)
    sent: list[float] = []
    send_now = backend._send_now

    def timed_send_now(q: np.ndarray, ticks: np.ndarray | None = None) -> np.ndarray:
        sent.append(time.monotonic())
        return send_now(q, ticks)

    backend._send_now = timed_send_now  # type: ignore[method-assign]
    with backend:
        backend.send(JointCommand(target, 0.0))
    ramp = np.diff(sent[:-1])  # the last: the command itself, once the ramp is there
    assert len(ramp) > 12
    # Half a period: the times are read beside the backend's own, not by it (0.2 ms before).
    assert ramp.min() >= 0.5 * period


def test_command_outside_limits_never_reaches_the_wire(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    safe = SafetyLayer(op3, DynamixelBackend(op3, make_buses(op3, op3_sim)))
    rng = np.random.default_rng(0)
    with safe:
        for k in range(200):
            # Far outside the limits, but within a turn (beyond it is refused as degrees).
            q = np.clip(op3.init_pose + rng.normal(0, 3.0, op3.num_joints), -6.0, 6.0)
            safe.send(JointCommand(q, k / op3.control_rate_hz))
        _settle(op3_sim)
    assert safe.stats.position_clips > 0
    units = ServoUnits(op3)
    lo_t, hi_t = units.to_ticks(op3.lower), units.to_ticks(op3.upper)
    lo_t, hi_t = np.minimum(lo_t, hi_t), np.maximum(lo_t, hi_t)
    for i, j in enumerate(op3.joints):
        goals = _goals_on_wire(sim, j.servo_id, 116)
        assert goals
        assert min(goals) >= lo_t[i]
        assert max(goals) <= hi_t[i]


def test_hardware_error_raises_servo_fault_and_torque_off(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    j = op3.joints[3]
    servo = op3_sim[j.bus].servos[j.servo_id]
    with backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        servo.inject_hardware_error(0x20 | 0x04)
        with pytest.raises(ServoFaultError) as info:
            backend.read_state()
        assert info.value.servo_id == j.servo_id
        assert set(info.value.bits) == {"overload", "overheating"}
        _settle(op3_sim)
        assert not any(s.torque_on for s in op3_sim[j.bus].servos.values())
        with pytest.raises(NotConnectedError, match="fault"):
            backend.send(JointCommand(op3.init_pose, 0.01))


def test_protocol1_hardware_error(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    j = poppy.joints[-1]
    servo = poppy_sim[j.bus].servos[j.servo_id]
    with DynamixelBackend(poppy, make_buses(poppy, poppy_sim)) as backend:
        backend.send(JointCommand(poppy.init_pose, 0.0))
        servo.inject_hardware_error(0x01)
        with pytest.raises(ServoFaultError, match="input voltage") as info:
            backend.read_state()
        assert info.value.servo_id == j.servo_id
        _settle(poppy_sim)
        assert not any(s.torque_on for b in poppy_sim.values() for s in b.servos.values())


def test_repeated_failures_raise_and_switch_torque_off(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    with backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        sim.faults.drop_replies = 10_000
        with pytest.raises(CommunicationError):
            backend.read_state()  # after the bounded retries (a hang trips the time limit)
        sim.settle()
        assert not any(s.torque_on for s in sim.servos.values())


def test_dropped_reply_is_retried_transparently(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    buses = make_buses(op3, op3_sim)
    with DynamixelBackend(op3, buses) as backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        sim.faults.drop_replies = 1
        state = backend.read_state()
        assert state.q.shape == (op3.num_joints,)
        assert next(iter(buses.values())).stats.retries >= 1
        assert backend.torque_on


def test_unplugged_port_is_a_clear_error_and_no_hang(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    backend.connect()
    backend.send(JointCommand(op3.init_pose, 0.0))
    sim.unplug()
    with pytest.raises(CommunicationError, match="unplugged"):
        backend.read_state()
    backend.disconnect()  # must not raise on a dead port


def test_nan_is_refused_and_torque_off_on_exception(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        sim.settle()
        n_packets = len(sim.log.packets)
        bad = op3.init_pose.copy()
        bad[2] = np.nan
        with pytest.raises(Exception, match="NaN"):
            backend.send(JointCommand(bad, 0.01))
        sim.settle()
        assert len(sim.log.packets) == n_packets  # nothing sent for the NaN command
        with pytest.raises(HardwareError, match="outside the joint limits"):
            backend.send(JointCommand(op3.init_pose + 10.0, 0.02))  # beyond the servo's range
        sim.settle()
        assert len(sim.log.packets) > n_packets  # the torque-off write, and no goal
        assert not any(s.torque_on for s in sim.servos.values())


def test_command_outside_joint_limits_is_refused_without_a_safety_layer(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    """Within the servo's range but past a joint's mechanical limit: the backend alone refuses
    it, names the joint, sends no goal and switches torque off."""
    sim = next(iter(op3_sim.values()))
    knee = op3.joint_index("l_knee")
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        sim.settle()
        goals_before = {sid: s.get("goal_position") for sid, s in sim.servos.items()}
        bad = op3.init_pose.copy()
        bad[knee] = op3.upper[knee] + 0.2
        with pytest.raises(UnsafeCommandError, match="l_knee") as info:
            backend.send(JointCommand(bad, 0.01))
        assert info.value.joints == ("l_knee",)
        sim.settle()
        assert {sid: s.get("goal_position") for sid, s in sim.servos.items()} == goals_before
        assert not any(s.torque_on for s in sim.servos.values())


def test_a_jump_is_refused_without_a_safety_layer(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    """Inside the limits but further than the velocity limit allows in one control period:
    the backend alone refuses it (a SafetyLayer in front bounds every step), sends no goal
    and switches torque off."""
    sim = next(iter(op3_sim.values()))
    shoulder = op3.joint_index("r_sho_pitch")
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.send(JointCommand(op3.init_pose, 0.0))
        step = op3.init_pose.copy()
        step[shoulder] += 0.9 * op3.max_velocity[shoulder] / op3.control_rate_hz
        backend.send(JointCommand(step, 0.008))  # within one period's reach: sent
        sim.settle()
        goals_before = {sid: s.get("goal_position") for sid, s in sim.servos.items()}
        jump = step.copy()
        jump[shoulder] = np.clip(step[shoulder] + 1.0, op3.lower[shoulder], op3.upper[shoulder])
        with pytest.raises(UnsafeCommandError, match="r_sho_pitch by") as info:
            backend.send(JointCommand(jump, 0.016))
        assert info.value.joints == ("r_sho_pitch",)
        sim.settle()
        assert {sid: s.get("goal_position") for sid, s in sim.servos.items()} == goals_before
        assert not any(s.torque_on for s in sim.servos.values())


def test_sigint_switches_torque_off(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    backend.connect()
    backend.send(JointCommand(op3.init_pose, 0.0))
    sim.settle()
    assert all(s.torque_on for s in sim.servos.values())
    with pytest.raises(KeyboardInterrupt):  # noqa: PT012 (the handler runs after os.kill)
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)
    sim.settle()
    assert not any(s.torque_on for s in sim.servos.values())
    assert not backend.connected
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_profile_settings_are_written(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    from dataclasses import replace

    from robot_retarget.robot.config import HardwareSettings

    cfg = replace(
        op3, hardware=HardwareSettings(profile_velocity_rad_s=1.0, profile_acceleration_rad_s2=10.0)
    )
    with DynamixelBackend(cfg, make_buses(cfg, op3_sim)):
        pass
    s = next(iter(op3_sim.values())).servos[1]
    assert s.get("profile_velocity") == 42  # 1 rad/s / (0.229 rpm) rounded up
    assert s.get("profile_acceleration") == 27  # 10 rad/s² = 5729.6 rev/min² / 214.577


def test_sigterm_switches_torque_off(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    previous = signal.getsignal(signal.SIGTERM)
    backend.connect()
    backend.send(JointCommand(op3.init_pose, 0.0))
    with pytest.raises(SystemExit) as info:  # noqa: PT012 (the handler runs after os.kill)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.5)
    assert info.value.code == 128 + signal.SIGTERM
    sim.settle()
    assert not any(s.torque_on for s in sim.servos.values())
    assert signal.getsignal(signal.SIGTERM) is previous


def test_disconnect_goes_to_the_safe_pose_first_when_configured(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    from dataclasses import replace

    sim = next(iter(op3_sim.values()))
    cfg = replace(op3, hardware=replace(op3.hardware, torque_off_at_safe_pose=True))
    start = np.clip(cfg.safe_pose + 0.05, cfg.lower, cfg.upper)
    with DynamixelBackend(cfg, make_buses(cfg, op3_sim), ramp_speed_fraction=1.0) as backend:
        backend.send(JointCommand(start, 0.0))
    sim.settle()
    safe_ticks = ServoUnits(cfg).to_ticks(cfg.safe_pose)
    for i, j in enumerate(cfg.joints):
        assert sim.servos[j.servo_id].get("goal_position") == safe_ticks[i]
        assert not sim.servos[j.servo_id].torque_on


def test_old_firmware_falls_back_to_plain_sync_read(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    sim.servos[op3.joints[0].servo_id]._put("firmware_version", 44)
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.read_state()
    sim.settle()
    instructions = {raw[7] for raw in list(sim.log.packets)}
    assert p.INST_SYNC_READ in instructions
    assert p.INST_FAST_SYNC_READ not in instructions


def test_fast_sync_read_is_used_when_supported(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    sim = next(iter(op3_sim.values()))
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.read_state()
    sim.settle()
    assert p.INST_FAST_SYNC_READ in {raw[7] for raw in list(sim.log.packets)}


def test_two_buses_are_read_at_once_and_equal_a_sequential_read(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    import threading

    backend = DynamixelBackend(poppy, make_buses(poppy, poppy_sim))
    second = backend.bus(poppy.buses[1].name)
    readers: set[str] = set()
    read_group = backend._read_group

    def spy(g):  # type: ignore[no-untyped-def]
        if g.bus is second:
            readers.add(threading.current_thread().name)
        return read_group(g)

    backend._read_group = spy  # type: ignore[method-assign]
    with backend:
        backend.send(JointCommand(poppy.init_pose, 0.0))
        _settle(poppy_sim)
        parallel = backend.read_state()
        backend.parallel_buses = False
        sequential = backend.read_state()
        np.testing.assert_array_equal(parallel.q, sequential.q)
        np.testing.assert_array_equal(parallel.temperature, sequential.temperature)
        assert any(name.startswith(f"{poppy.name}-bus") for name in readers)
        assert threading.main_thread().name in readers
    # Disconnect ends the worker thread.
    assert not any(t.name.startswith(f"{poppy.name}-bus") for t in threading.enumerate())


def test_a_dead_second_bus_stops_both_buses(
    poppy: RobotConfig, poppy_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    backend = DynamixelBackend(poppy, make_buses(poppy, poppy_sim))
    with backend:
        backend.send(JointCommand(poppy.init_pose, 0.0))
        poppy_sim[poppy.buses[1].name].faults.drop_replies = 10_000
        with pytest.raises(CommunicationError):
            backend.read_state()  # raised in the worker thread, seen here
        _settle(poppy_sim)
        assert not any(s.torque_on for s in poppy_sim[poppy.buses[0].name].servos.values())
        assert not any(s.torque_on for s in poppy_sim[poppy.buses[1].name].servos.values())


def test_commands_faster_than_real_time_are_refused_without_a_safety_layer(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    """Each command within a period's reach, stamped a period apart, but sent with no time
    between them: the backend alone lets its clock budget (BACKEND_BUDGET_PERIODS' worth) go,
    then refuses, sends nothing and switches torque off."""
    sim = next(iter(op3_sim.values()))
    clock = FakeClock()
    shoulder = op3.joint_index("r_sho_pitch")
    reach = 0.9 * op3.max_velocity[shoulder] / op3.control_rate_hz
    sign = 1.0 if op3.upper[shoulder] - op3.init_pose[shoulder] > 0.5 else -1.0
    with DynamixelBackend(op3, make_buses(op3, op3_sim)) as backend:
        backend.set_command_clock(clock.now)
        q = op3.init_pose.copy()
        backend.send(JointCommand(q, 0.0))  # torque on where the servos are, then a ramp
        taken = int(BACKEND_BUDGET_PERIODS / 0.9)  # 0.9 of a period's reach each: taken
        for k in range(1, taken + 1):
            q[shoulder] += sign * reach
            backend.send(JointCommand(q, k / op3.control_rate_hz))
        q[shoulder] += sign * reach
        with pytest.raises(UnsafeCommandError, match="faster than real time") as info:
            backend.send(JointCommand(q, (taken + 1) / op3.control_rate_hz))
        assert info.value.joints == ("r_sho_pitch",)
        sim.settle()
        assert not any(s.torque_on for s in sim.servos.values())


def test_behind_a_safety_layer_the_clock_budget_never_refuses(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    """The same commands through a SafetyLayer on the same clock: held to the time that
    passed (a tenth of a period per command), never refused by the backend."""
    clock = FakeClock()
    safe = SafetyLayer(op3, DynamixelBackend(op3, make_buses(op3, op3_sim)), clock=clock.now)
    shoulder = op3.joint_index("r_sho_pitch")
    sign = 1.0 if op3.upper[shoulder] - op3.init_pose[shoulder] > 0.5 else -1.0
    with safe:
        q = op3.init_pose.copy()
        safe.send(JointCommand(q, 0.0))
        for k in range(1, 60):
            clock.t += 0.1 / op3.control_rate_hz
            q[shoulder] += sign * op3.max_velocity[shoulder] / op3.control_rate_hz
            safe.send(JointCommand(q, k / op3.control_rate_hz))
        assert safe.stats.clock_clips > 0
        assert safe.backend.connected


def test_behind_a_safety_layer_a_joint_dithering_across_a_tick_is_never_refused(
    op3: RobotConfig, op3_sim: dict[str, SimulatedBus], make_buses: MakeBuses
) -> None:
    """Commands faster than real time that dither a joint across a tick's edge: each writes a
    whole tick, which the backend's budget counts, so the layer counts it too (it had counted
    the 2e-6 rad asked for, and the backend then refused a step the layer let through, torque
    off)."""
    clock = FakeClock()
    backend = DynamixelBackend(op3, make_buses(op3, op3_sim))
    safe = SafetyLayer(op3, backend, clock=clock.now)
    period = 1.0 / op3.control_rate_hz
    j = op3.joint_index("r_sho_pitch")
    with safe:
        q = np.array(safe.read_state().q)
        safe.send(JointCommand(q, 0.0))  # torque on where the servos are
        tick = float(backend.units.rad_per_tick[j])
        edge = float(safe.rounded(q)[j]) + 0.5 * tick
        n = int(BACKEND_BUDGET_PERIODS * op3.max_velocity[j] * period / tick) + 3
        for k in range(1, n + 1):
            q[j] = edge + (1e-6 if k % 2 else -1e-6)
            safe.send(JointCommand(q, k * period))
        q[j] = edge + 0.9 * op3.max_velocity[j] * period
        safe.send(JointCommand(q, (n + 1) * period))  # held to the clock, not refused
        assert safe.backend.connected
        assert safe.stats.clock_clips > 0
