"""A conversion job's manifest: ``manifest.json`` in the output folder, one entry per clip.

Each entry holds the clip (relative to the input folder), the SHA-256 of its bytes, its status
(``pending``, ``done``, ``failed``), frame count, fidelity figures (limits respected, largest
position/velocity excess, safety-layer clips, solver fallbacks), compute seconds, outputs and
error. The file is rewritten atomically (temporary file + ``os.replace``) after every clip, so
a job killed at any moment leaves a manifest that lists every clip that finished. A re-run with
the same settings skips the clips that are done (same hash, outputs present) and converts the
rest; outputs of clips the manifest lists as pending or failed belong to the job and are
replaced without --force.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from robot_retarget.errors import RetargetError
from robot_retarget.pipeline.clip_converter import ClipReport

MANIFEST_NAME = "manifest.json"
_VERSION = 1

PENDING = "pending"
DONE = "done"
FAILED = "failed"


class ManifestError(RetargetError):
    """The manifest in an output folder cannot be used: ``path`` the manifest, ``reason``
    why (unreadable, written by other settings)."""

    def __init__(self, message: str, *, path: str | Path, reason: str) -> None:
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {message}")


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@dataclass
class ClipEntry:
    clip: str
    sha256: str
    status: str = PENDING
    outputs: list[str] = field(default_factory=list)
    frames: int = 0
    wall_s: float = 0.0
    limits_ok: bool = False
    position_excess_rad: float = 0.0
    velocity_excess_rad: float = 0.0
    clipped_commands: int = 0
    clipped_joints: int = 0
    fallbacks: int = 0
    error: str | None = None
    lead_in_frames: int = 0


class Manifest:
    """The clips of one output folder. ``settings`` are the options every output was made
    with (robot, model, fps, ...): a re-run with other settings is refused."""

    def __init__(self, path: Path, settings: dict[str, Any], entries: dict[str, ClipEntry]) -> None:
        self.path = path
        self.settings = settings
        self.entries = entries

    @classmethod
    def open(cls, out_dir: Path, settings: dict[str, Any], *, fresh: bool = False) -> Manifest:
        """The manifest in ``out_dir`` (an empty one when there is none, or with ``fresh``)."""
        path = out_dir / MANIFEST_NAME
        if fresh or not path.is_file():
            return cls(path, settings, {})
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            entries = {e["clip"]: ClipEntry(**e) for e in data["clips"]}
            old = data["settings"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ManifestError(
                f"cannot read it ({exc}); remove it, or pass --force to start the job afresh",
                path=path,
                reason="unreadable",
            ) from exc
        if old != settings:
            changed = sorted(k for k in {*old, *settings} if old.get(k) != settings.get(k))
            # A setting added since the manifest was written (e.g. foot_lock) was then fixed
            # by the code of that day: say so rather than leave the user to guess.
            unrecorded = [k for k in changed if k not in old]
            since = f" ({', '.join(unrecorded)}: not recorded by the version that wrote it)"
            raise ManifestError(
                f"its outputs were made with other settings ({', '.join(changed)})"
                f"{since if unrecorded else ''}; use another output folder, or pass --force to "
                "convert every clip again",
                path=path,
                reason="settings",
            )
        return cls(path, settings, entries)

    def is_done(self, key: str, sha256: str, outputs: list[Path]) -> bool:
        e = self.entries.get(key)
        return (
            e is not None
            and e.status == DONE
            and e.sha256 == sha256
            and all(p.is_file() for p in outputs)
        )

    def owns(self, key: str) -> bool:
        """The clip was part of an earlier run of this job: its outputs may be replaced."""
        return key in self.entries

    def mark_pending(self, key: str, sha256: str, outputs: list[Path]) -> None:
        self.entries[key] = ClipEntry(key, sha256, PENDING, [str(p) for p in outputs])

    def record(self, key: str, report: ClipReport) -> ClipEntry:
        prev = self.entries[key]
        fields = asdict(report)
        entry = ClipEntry(
            clip=key,
            sha256=prev.sha256,
            status=FAILED if report.error is not None else DONE,
            outputs=prev.outputs,
            **{k: fields[k] for k in _REPORT_FIELDS},
        )
        self.entries[key] = entry
        return entry

    def save(self) -> None:
        """Write atomically: a reader (or a re-run after a kill) never sees half a file."""
        data = {
            "version": _VERSION,
            "settings": self.settings,
            "clips": [asdict(e) for _, e in sorted(self.entries.items())],
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".manifest-", suffix=".tmp", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(data, f, indent=1)
                f.write("\n")
            os.replace(tmp, self.path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise


_REPORT_FIELDS = (
    "frames",
    "wall_s",
    "limits_ok",
    "position_excess_rad",
    "velocity_excess_rad",
    "clipped_commands",
    "clipped_joints",
    "fallbacks",
    "error",
    "lead_in_frames",
)
