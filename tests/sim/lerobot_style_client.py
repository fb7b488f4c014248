"""A LeRobot-style client of a simulated OP3 bus, run in its own process as LeRobot would be:
``python tests/sim/lerobot_style_client.py PORT SESSIONS`` prints ``PASSED n/SESSIONS RETRIES r``.

What LeRobot's DynamixelMotorsBus does, through the ROBOTIS SDK: ping the models, write a
calibration (Homing_Offset, Drive_Mode), sync-write goals, sync-read present positions in the
calibrated frame. Its own process, like the pypot client's: a client sharing the simulator's
interpreter would share its GIL, and a real servo answers whatever its host is doing.
"""

from __future__ import annotations

import sys

import dynamixel_sdk as sdk

from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config

# A reply that does not come within the SDK's packet timeout (≈ 34 ms) is asked for again, as
# LeRobot's bus does with num_retry: on a loaded 2-core machine the simulator's thread can miss
# that window. Wrong bytes, CRC errors or refused packets are never retried.
_RETRIES_PER_CALL = 2
retries = 0
failures: list[str] = []  # what went wrong, per failed session (printed on stderr)


def _with_retry(call):  # type: ignore[no-untyped-def]
    global retries
    for attempt in range(1 + _RETRIES_PER_CALL):
        result = call()
        comm = result[1] if isinstance(result, tuple) else result
        if comm != sdk.COMM_RX_TIMEOUT or attempt == _RETRIES_PER_CALL:
            return result
        retries += 1
    return result


def _lerobot_style_session(port: str, config: RobotConfig, k: int) -> bool:
    """What LeRobot's DynamixelMotorsBus does: ping models, write a calibration
    (Homing_Offset, Drive_Mode), sync-write goals, sync-read present positions."""
    ids = [j.servo_id for j in config.joints]
    handler = sdk.PortHandler(port)
    if not (handler.openPort() and handler.setBaudRate(config.buses[0].baud_rate)):
        failures.append(f"session {k}: could not open {port}")
        return False
    packet = sdk.PacketHandler(2.0)
    try:
        for sid in ids:
            model, comm, _err = _with_retry(lambda sid=sid: packet.ping(handler, sid))
            if comm != sdk.COMM_SUCCESS or model != 1020:  # XM430-W350
                failures.append(f"session {k}: ping {sid}: comm {comm}, model {model}")
                return False

        def sync_read(address: int) -> dict[int, int] | None:
            reader = sdk.GroupSyncRead(handler, packet, address, 4)
            for sid in ids:
                reader.addParam(sid)
            comm = _with_retry(reader.txRxPacket)
            if comm != sdk.COMM_SUCCESS:
                failures.append(f"session {k}: sync read at {address}: comm {comm}")
                return None
            return {sid: reader.getData(sid, address, 4) for sid in ids}

        for sid in ids:  # a clean calibration first
            packet.write1ByteTxRx(handler, sid, 64, 0)  # torque off: EEPROM
            packet.write4ByteTxRx(handler, sid, 20, 0)
            packet.write1ByteTxRx(handler, sid, 10, 0)
        before = sync_read(132)  # Present_Position
        homing = 100 + k
        calibrated = set(ids[: len(ids) // 2])
        for sid in calibrated:  # LeRobot's calibration: Homing_Offset per motor
            packet.write4ByteTxRx(handler, sid, 20, homing)
        after = sync_read(132)
        if before is None or after is None:
            return False
        ok = all(after[sid] - before[sid] == (homing if sid in calibrated else 0) for sid in ids)
        writer = sdk.GroupSyncWrite(handler, packet, 116, 4)  # Goal_Position
        goals = {sid: after[sid] + (-1) ** k * 20 for sid in ids}
        for sid, g in goals.items():
            writer.addParam(sid, list(g.to_bytes(4, "little")))
        for sid in ids:
            packet.write1ByteTxRx(handler, sid, 64, 1)
        if not ok:
            failures.append(f"session {k}: calibration not applied: {before} → {after}")
        ok &= writer.txPacket() == sdk.COMM_SUCCESS
        read_goals = sync_read(116)
        if read_goals != goals:
            failures.append(f"session {k}: goals {goals} read back as {read_goals}")
        ok &= read_goals == goals
        for sid in ids:
            packet.write1ByteTxRx(handler, sid, 64, 0)
            packet.write4ByteTxRx(handler, sid, 20, 0)
        return bool(ok)
    finally:
        handler.closePort()


if __name__ == "__main__":
    port, sessions = sys.argv[1], int(sys.argv[2])
    op3 = load_robot_config("op3")
    passed = sum(_lerobot_style_session(port, op3, k) for k in range(sessions))
    print(f"PASSED {passed}/{sessions} RETRIES {retries}")
    print("\n".join(failures), file=sys.stderr)
