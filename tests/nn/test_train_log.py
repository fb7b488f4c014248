"""Training logs: CSV rows and TensorBoard event records that TensorBoard's reader accepts."""

from __future__ import annotations

import csv
import struct
from pathlib import Path

import pytest

from robot_retarget.nn.train_log import TrainLog, crc32c, masked_crc32c, record_bytes


def test_crc32c_check_value() -> None:
    # The standard CRC-32C check value (RFC 3720, "123456789").
    assert crc32c(b"123456789") == 0xE3069283
    assert crc32c(b"") == 0


def test_record_frame_layout() -> None:
    payload = b"hello"
    rec = record_bytes(payload)
    (length,) = struct.unpack("<Q", rec[:8])
    assert length == 5
    assert struct.unpack("<I", rec[8:12])[0] == masked_crc32c(rec[:8])
    assert rec[12:17] == payload
    assert struct.unpack("<I", rec[17:21])[0] == masked_crc32c(payload)


def test_csv_appends_across_sessions(tmp_path: Path) -> None:
    with TrainLog(tmp_path) as log:
        log.scalars(1, "train", {"loss": 0.5, "x": 2.0})
    with TrainLog(tmp_path) as log:
        log.scalars(2, "val", {"loss": 0.25})
    rows = list(csv.DictReader((tmp_path / "log.csv").open()))
    assert [(r["step"], r["split"], r["metric"], float(r["value"])) for r in rows] == [
        ("1", "train", "loss", 0.5),
        ("1", "train", "x", 2.0),
        ("2", "val", "loss", 0.25),
    ]


def test_tensorboard_reads_the_events(tmp_path: Path) -> None:
    accumulator = pytest.importorskip(
        "tensorboard.backend.event_processing.event_accumulator",
        reason="tensorboard is not installed (optional; the format is still tested above)",
    )
    with TrainLog(tmp_path) as log:
        log.scalars(3, "train", {"loss": 1.5})
        log.scalars(7, "val", {"score": 0.125})
    acc = accumulator.EventAccumulator(str(tmp_path))
    acc.Reload()
    assert set(acc.Tags()["scalars"]) == {"train/loss", "val/score"}
    (event,) = acc.Scalars("val/score")
    assert (event.step, event.value) == (7, 0.125)


def test_a_resumed_log_goes_on_from_its_last_elapsed_time(tmp_path: Path) -> None:
    """A resume's rows had restarted elapsed_s at 0 (2.399 s at step 20, then 1.100 s at 30)."""
    import time

    with TrainLog(tmp_path, start_time_s=time.time() - 50.0) as log:
        log.scalars(20, "train", {"total": 1.0})
    with TrainLog(tmp_path) as log:  # the resume
        log.scalars(30, "train", {"total": 0.5})
    with (tmp_path / "log.csv").open(newline="") as f:
        elapsed = [float(r["elapsed_s"]) for r in csv.DictReader(f)]
    assert elapsed[0] >= 50.0
    assert elapsed[1] >= elapsed[0]
