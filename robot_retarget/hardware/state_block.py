"""A contiguous span of control-table registers read from many servos, decoded by register name.

The backend reads one block per servo per tick (Sync / Fast Sync / Bulk Read): the span from
its first to its last register. Where each register sits inside the span, how wide it is and
how it is signed comes from :mod:`robot_retarget.hardware.control_table`, never from offsets
written by hand. Decoding works on all servos at once: an (N, span) byte matrix in, one int64
array of N values per register out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import IntArray
from robot_retarget.hardware.control_table import ControlTable

ByteMatrix = npt.NDArray[np.uint8]


@dataclass(frozen=True)
class _Field:
    name: str
    offset: int  # bytes from the block's start
    size: int
    signed: bool
    sign_magnitude_bit: int | None  # Protocol 1.0 speed / load: direction in this bit


class StateBlock:
    """Registers ``names`` of ``table``, read as one span from the lowest to the highest."""

    def __init__(self, table: ControlTable, names: Sequence[str]) -> None:
        if not names:
            raise ValueError("a state block needs at least one register")
        regs = [table[n] for n in names]
        self.table = table
        self.address = min(r.address for r in regs)
        self.size = max(r.address + r.size for r in regs) - self.address
        sign_magnitude = {"present_speed", "present_load"} if table.sign_magnitude_bit else set()
        self._fields = {
            r.name: _Field(
                r.name,
                r.address - self.address,
                r.size,
                r.signed,
                table.sign_magnitude_bit if r.name in sign_magnitude else None,
            )
            for r in regs
        }
        # Sign-magnitude registers are read unsigned; value() applies the direction bit.
        self._dtype = np.dtype(
            {
                "names": [f.name for f in self._fields.values()],
                "formats": [
                    f"<{'i' if f.signed and f.sign_magnitude_bit is None else 'u'}{f.size}"
                    for f in self._fields.values()
                ],
                "offsets": [f.offset for f in self._fields.values()],
                "itemsize": self.size,
            }
        )

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._fields)

    def __contains__(self, name: object) -> bool:
        return name in self._fields

    def matches(self, other: ControlTable) -> bool:
        """Whether ``other`` has the same registers at the same places (one read serves both)."""
        try:
            return all(
                other[f.name].address - self.address == f.offset and other[f.name].size == f.size
                for f in self._fields.values()
            )
        except KeyError:
            return False

    def records(self, data: ByteMatrix) -> npt.NDArray[np.void]:
        """Every servo's block as one record with a field per register (a view, no decoding
        loop): ``data`` holds one block per row."""
        return np.ascontiguousarray(data).view(self._dtype)[:, 0]

    def value(self, records: npt.NDArray[np.void], name: str) -> IntArray:
        """Register ``name`` of every servo, from :meth:`records`."""
        raw = records[name].astype(np.int64)
        f = self._fields[name]
        if f.sign_magnitude_bit is None:
            return raw
        bit = 1 << f.sign_magnitude_bit
        magnitude = raw & (bit - 1)
        return np.where(raw & bit, -magnitude, magnitude)

    def decode(self, data: ByteMatrix, name: str) -> IntArray:
        """Register ``name`` of every servo: ``data`` holds one block per row."""
        return self.value(self.records(data), name)


def stack_blocks(blocks: Sequence[bytes], size: int) -> ByteMatrix:
    """Per-servo byte strings (each ``size`` long) as an (N, size) matrix."""
    return np.frombuffer(b"".join(blocks), dtype=np.uint8).reshape(len(blocks), size)
