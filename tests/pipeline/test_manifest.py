"""The conversion manifest: round trip, atomic saves, what counts as done, other settings."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_retarget.pipeline.clip_converter import ClipReport
from robot_retarget.pipeline.manifest import (
    DONE,
    FAILED,
    MANIFEST_NAME,
    PENDING,
    Manifest,
    ManifestError,
    file_sha256,
)

SETTINGS = {"robot": "op3", "model": "default", "fps": None}


def _report(clip: Path, out: Path, error: str | None = None) -> ClipReport:
    return ClipReport(clip, out, frames=12, wall_s=0.5, limits_ok=True, fallbacks=1, error=error)


def test_round_trip_and_what_is_done(tmp_path: Path) -> None:
    clip, out = tmp_path / "a.bvh", tmp_path / "out" / "a.npz"
    clip.write_text("clip")
    digest = file_sha256(clip)
    m = Manifest.open(tmp_path / "out", SETTINGS)
    m.mark_pending("a.bvh", digest, [out])
    m.save()
    assert Manifest.open(tmp_path / "out", SETTINGS).entries["a.bvh"].status == PENDING
    m.record("a.bvh", _report(clip, out))
    m.save()
    loaded = Manifest.open(tmp_path / "out", SETTINGS)
    entry = loaded.entries["a.bvh"]
    assert (entry.status, entry.frames, entry.fallbacks, entry.limits_ok) == (DONE, 12, 1, True)
    assert not loaded.is_done("a.bvh", digest, [out])  # its output is missing
    out.write_bytes(b"npz")
    assert loaded.is_done("a.bvh", digest, [out])
    assert not loaded.is_done("a.bvh", "0" * 64, [out])  # the clip changed since
    assert loaded.owns("a.bvh")
    assert not loaded.owns("b.bvh")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "a.npz",
        MANIFEST_NAME,
    ]  # no temp


def test_failed_clip_keeps_its_error(tmp_path: Path) -> None:
    m = Manifest.open(tmp_path, SETTINGS)
    m.mark_pending("x.bvh", "ab", [tmp_path / "x.npz"])
    m.record("x.bvh", _report(tmp_path / "x.bvh", tmp_path / "x.npz", error="line 3: bad"))
    m.save()
    entry = Manifest.open(tmp_path, SETTINGS).entries["x.bvh"]
    assert (entry.status, entry.error) == (FAILED, "line 3: bad")


def test_other_settings_and_unreadable_files_are_refused(tmp_path: Path) -> None:
    m = Manifest.open(tmp_path, SETTINGS)
    m.save()
    with pytest.raises(ManifestError, match="fps") as info:
        Manifest.open(tmp_path, {**SETTINGS, "fps": 30.0})
    assert info.value.reason == "settings"
    assert "not recorded" not in str(info.value)
    # A setting added since the manifest was written is named as such.
    with pytest.raises(ManifestError, match=r"foot_lock: not recorded by the version"):
        Manifest.open(tmp_path, {**SETTINGS, "foot_lock": False})
    assert Manifest.open(tmp_path, {**SETTINGS, "fps": 30.0}, fresh=True).entries == {}
    (tmp_path / MANIFEST_NAME).write_text("{ half a fi")
    with pytest.raises(ManifestError, match="--force") as info:
        Manifest.open(tmp_path, SETTINGS)
    assert info.value.reason == "unreadable"
