"""A folder conversion driven by its manifest: skip what is done, convert the rest on a pool.

:func:`plan_batch` sorts the clips of a job into those already done (skipped) and those to
convert, and marks the latter pending in the manifest (saved before any work, so the outputs a
killed job leaves behind belong to it). :func:`run_batch` feeds them to a pool
(robot_retarget.pipeline.clip_pool) and records each report in the manifest as it arrives; a
failed clip is recorded and the job goes on.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from robot_retarget.pipeline.clip_converter import ClipJob, ClipReport
from robot_retarget.pipeline.manifest import Manifest, file_sha256


class ClipPool(Protocol):
    def convert(self, jobs: Sequence[ClipJob]) -> Iterator[ClipReport]: ...


@dataclass(frozen=True)
class BatchPlan:
    todo: list[ClipJob]
    skipped: list[ClipJob]
    keys: dict[Path, str]  # clip → its manifest key


def clip_key(clip: Path, root: Path) -> str:
    return clip.relative_to(root).as_posix() if clip != root else clip.name


def plan_batch(jobs: Sequence[ClipJob], root: Path, manifest: Manifest) -> BatchPlan:
    """Which clips still need converting; marks them pending and saves the manifest. A clip
    whose content hash changed since it was done is converted again."""
    todo: list[ClipJob] = []
    skipped: list[ClipJob] = []
    keys: dict[Path, str] = {}
    for job in jobs:
        key = clip_key(job.clip, root)
        keys[job.clip] = key
        digest = file_sha256(job.clip)
        if manifest.is_done(key, digest, job.outputs()):
            skipped.append(job)
            continue
        manifest.mark_pending(key, digest, job.outputs())
        todo.append(job)
    manifest.save()
    return BatchPlan(todo, skipped, keys)


def run_batch(
    plan: BatchPlan,
    manifest: Manifest,
    pool: ClipPool,
    on_report: Callable[[ClipReport], None] | None = None,
) -> list[ClipReport]:
    """Convert ``plan.todo`` on ``pool``; the manifest is saved after every clip."""
    reports: list[ClipReport] = []
    for report in pool.convert(plan.todo):
        manifest.record(plan.keys[report.clip], report)
        manifest.save()
        reports.append(report)
        if on_report is not None:
            on_report(report)
    return reports
