"""Training logs: a long-format CSV and a TensorBoard event file, with no extra dependency.

``log.csv`` has one row per scalar (step, elapsed_s, split, metric, value), easy to load in
pandas or a spreadsheet. ``events.out.tfevents.*`` is TensorBoard's format — TFRecord frames
(length, masked CRC-32C, payload, masked CRC-32C) around ``Event`` protocol buffers holding
``Summary.Value(tag, simple_value)`` — written by hand so that ``tensorboard --logdir runs/``
works without TensorFlow or tensorboardX in the product's dependencies.
"""

from __future__ import annotations

import contextlib
import csv
import socket
import struct
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO

CSV_FIELDS = ("step", "elapsed_s", "split", "metric", "value")


def _crc32c_table() -> list[int]:
    table = []
    for n in range(256):
        c = n
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1  # Castagnoli, reflected
        table.append(c)
    return table


_CRC_TABLE = _crc32c_table()


def crc32c(data: bytes) -> int:
    """CRC-32C (Castagnoli) of ``data``, as TFRecord frames use."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc = _CRC_TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


def masked_crc32c(data: bytes) -> int:
    """TFRecord's masked CRC: rotate right by 15 and add a constant."""
    crc = crc32c(data)
    return (((crc >> 15) | (crc << 17)) + 0xA282EAD8) & 0xFFFFFFFF


def _varint(value: int) -> bytes:
    out = bytearray()
    v = value & 0xFFFFFFFFFFFFFFFF  # int64 on the wire: two's complement
    while True:
        bits = v & 0x7F
        v >>= 7
        if v:
            out.append(bits | 0x80)
        else:
            out.append(bits)
            return bytes(out)


def _field_bytes(number: int, payload: bytes) -> bytes:
    """A length-delimited protobuf field."""
    return _varint(number << 3 | 2) + _varint(len(payload)) + payload


def event_bytes(
    wall_time_s: float,
    step: int,
    *,
    scalars: Mapping[str, float] | None = None,
    file_version: str | None = None,
) -> bytes:
    """A serialised ``Event`` (wall_time = 1, step = 2, file_version = 3, summary = 5)."""
    out = bytearray(_varint(1 << 3 | 1) + struct.pack("<d", wall_time_s))
    out += _varint(2 << 3 | 0) + _varint(step)
    if file_version is not None:
        out += _field_bytes(3, file_version.encode())
    if scalars:
        values = b"".join(
            _field_bytes(
                1,  # Summary.value
                _field_bytes(1, tag.encode())  # Value.tag
                + _varint(2 << 3 | 5)  # Value.simple_value (float32)
                + struct.pack("<f", float(value)),
            )
            for tag, value in scalars.items()
        )
        out += _field_bytes(5, values)
    return bytes(out)


def record_bytes(payload: bytes) -> bytes:
    """One TFRecord frame around ``payload``."""
    length = struct.pack("<Q", len(payload))
    return (
        length
        + struct.pack("<I", masked_crc32c(length))
        + payload
        + struct.pack("<I", masked_crc32c(payload))
    )


def _last_elapsed_s(csv_path: Path) -> float:
    """The elapsed_s of a log's last row (0 for a log without one)."""
    last = 0.0
    with csv_path.open(newline="") as f:
        for row in csv.DictReader(f):
            with contextlib.suppress(KeyError, TypeError, ValueError):
                last = float(row["elapsed_s"])
    return last


class TrainLog:
    """Appends scalars to ``<folder>/log.csv`` and to a TensorBoard event file in ``folder``.

    Appending (not truncating) lets a resumed run continue the same logs.
    """

    def __init__(self, folder: str | Path, *, start_time_s: float | None = None) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        csv_path = self.folder / "log.csv"
        new = not csv_path.exists()
        if start_time_s is None:  # a resumed run's elapsed_s goes on from its last row
            start_time_s = time.time() - (0.0 if new else _last_elapsed_s(csv_path))
        self.start_time_s = start_time_s
        self._csv_file: IO[str] = csv_path.open("a", newline="")
        self._csv = csv.writer(self._csv_file)
        if new:
            self._csv.writerow(CSV_FIELDS)
        now = time.time()
        name = f"events.out.tfevents.{int(now)}.{socket.gethostname()}"
        self.events_path = self.folder / name
        self._events: IO[bytes] = self.events_path.open("ab")
        self._events.write(record_bytes(event_bytes(now, 0, file_version="brain.Event:2")))

    def scalars(self, step: int, split: str, values: Mapping[str, float]) -> None:
        """Log ``values`` at ``step``; TensorBoard tags are ``split/metric``."""
        now = time.time()
        elapsed = now - self.start_time_s
        for metric, value in values.items():
            self._csv.writerow([step, f"{elapsed:.3f}", split, metric, repr(float(value))])
        tagged = {f"{split}/{k}": v for k, v in values.items()}
        self._events.write(record_bytes(event_bytes(now, step, scalars=tagged)))

    def flush(self) -> None:
        self._csv_file.flush()
        self._events.flush()

    def close(self) -> None:
        self._csv_file.close()
        self._events.close()

    def __enter__(self) -> TrainLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
