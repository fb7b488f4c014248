"""A LeRobot-style client of a simulated OP3 bus, run in its own process as LeRobot would be:
``python tests/sim/lerobot_style_client.py PORT SESSIONS`` prints ``PASSED n/SESSIONS``.

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


def _lerobot_style_session(port: str, config: RobotConfig, k: int) -> bool:
    """What LeRobot's DynamixelMotorsBus does: ping models, write a calibration
    (Homing_Offset, Drive_Mode), sync-write goals, sync-read present positions."""
    ids = [j.servo_id for j in config.joints]
    handler = sdk.PortHandler(port)
    if not (handler.openPort() and handler.setBaudRate(config.buses[0].baud_rate)):
        return False
    packet = sdk.PacketHandler(2.0)
    try:
        for sid in ids:
            model, comm, _err = packet.ping(handler, sid)
            if comm != sdk.COMM_SUCCESS or model != 1020:  # XM430-W350
                return False

        def sync_read(address: int) -> dict[int, int] | None:
            reader = sdk.GroupSyncRead(handler, packet, address, 4)
            for sid in ids:
                reader.addParam(sid)
            if reader.txRxPacket() != sdk.COMM_SUCCESS:
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
        ok &= writer.txPacket() == sdk.COMM_SUCCESS
        ok &= sync_read(116) == goals
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
    print(f"PASSED {passed}/{sessions}")
