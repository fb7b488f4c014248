"""The goal-position Sync Write of one bus, laid out once and refilled every tick.

Header, instruction, address, data length and servo IDs never change while streaming: they are
written into a buffer when the bus is set up, and each tick only drops the new tick values into
their slots (one numpy assignment) and appends the CRC or checksum. The bytes are the ones
:meth:`robot_retarget.hardware.bus.DynamixelBus.sync_write_packet` builds; a Protocol 2.0
payload that would need byte stuffing (``FF FF FD``, only possible for negative ticks) takes
that general path instead.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import IntArray
from robot_retarget.hardware import protocol as p

_STUFFING_PATTERN = b"\xff\xff\xfd"


class GoalPacket:
    """Sync Write of ``size``-byte values at ``address`` to servos ``ids`` (in this order)."""

    def __init__(self, protocol: float, address: int, size: int, ids: Sequence[int]) -> None:
        if size not in (1, 2, 4):
            raise ValueError(f"register size must be 1, 2 or 4 bytes, got {size}")
        self.protocol = float(protocol)
        self.address = address
        self.size = size
        self.ids = tuple(ids)
        n = len(self.ids)
        self._value_dtype = np.dtype(f"<i{size}")
        self._slots: npt.NDArray[np.uint8] = np.zeros((n, 1 + size), dtype=np.uint8)
        self._slots[:, 0] = self.ids
        self._v2 = self.protocol == 2.0
        if self._v2:
            self._params_head = p.le_bytes(address, 2) + p.le_bytes(size, 2)
            length = 1 + len(self._params_head) + n * (1 + size) + 2  # INST + PARAMS + CRC
            self._head = p.HEADER_V2 + bytes(
                (p.BROADCAST_ID, length & 0xFF, length >> 8, p.INST_SYNC_WRITE)
            )
        else:
            self._params_head = bytes((address, size))
            length = n * (1 + size) + 4  # INST + address + size + slots + checksum
            if length > 0xFF:
                raise ValueError(f"Protocol 1.0 Sync Write too long for {n} servos")
            self._head = p.HEADER_V1 + bytes((p.BROADCAST_ID, length, p.INST_SYNC_WRITE))
        self._prefix = self._head + self._params_head
        # Protocol 1.0 checksum covers everything after the header: its constant part, once.
        self._prefix_sum = sum(self._prefix[2:]) + sum(self.ids)

    def build(self, values: IntArray) -> bytes:
        """The complete packet for ``values`` (one per ID, in ID order)."""
        raw = np.asarray(values).astype(self._value_dtype)
        self._slots[:, 1:] = raw.view(np.uint8).reshape(len(self.ids), self.size)
        body = self._slots.tobytes()
        if self._v2:
            if _STUFFING_PATTERN in body:
                return p.build_v2(p.BROADCAST_ID, p.INST_SYNC_WRITE, self._params_head + body)
            packet = self._prefix + body
            crc = p.crc16_packet(packet)
            return packet + bytes((crc & 0xFF, crc >> 8))
        total = self._prefix_sum + int(self._slots[:, 1:].sum(dtype=np.int64))
        return self._prefix + body + bytes(((~total) & 0xFF,))
