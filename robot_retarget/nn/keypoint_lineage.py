"""Which subjects a keypoint checkpoint has seen, through the runs it came from.

A run that starts from a checkpoint (``--init-from``) or learns from one (``--distill-from``)
inherits what that checkpoint saw: the subjects it trained on, and those its best checkpoint was
chosen on. If those include the new run's validation or test-fold subjects, the new run's
numbers on them are not numbers on performers it never saw. A checkpoint's metadata names its
own run's subjects and the checkpoints it started from or learned from; those are followed
where their files still exist (a file that is gone cannot be, and is named in the refusal's
place as ``unfollowed``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_retarget.errors import RetargetError


class LineageError(RetargetError):
    """A checkpoint has seen subjects the run must not learn from (names them and the option)."""


@dataclass(frozen=True)
class Lineage:
    """Subjects trained on and chosen on by a checkpoint's run and every run it came from;
    ``recorded``: whether the checkpoint's own run names its training subjects."""

    trained: frozenset[str]
    validated: frozenset[str]
    recorded: bool
    unfollowed: tuple[str, ...]


def _parents(meta: dict[str, Any]) -> list[str]:
    parents = [str(meta["init_from"])] if meta.get("init_from") else []
    parents += [str(d["checkpoint"]) for d in meta.get("distilled_from") or () if "checkpoint" in d]
    return parents


def lineage(payload: dict[str, Any]) -> Lineage:
    """The subjects ``payload`` (a keypoint checkpoint's contents) and its ancestors saw."""
    from robot_retarget.nn.agnostic2d_training import keypoint_payload  # it imports this module

    trained: set[str] = set()
    validated: set[str] = set()
    unfollowed: list[str] = []
    meta = payload.get("metadata") or {}
    recorded = meta.get("train_subjects") is not None
    todo: list[dict[str, Any]] = [meta]
    followed: set[Path] = set()
    while todo:
        m = todo.pop()
        trained.update(m.get("train_subjects") or ())
        validated.update(m.get("validation_subjects") or ())
        for parent in _parents(m):
            path = Path(parent).resolve()
            if path in followed:
                continue
            followed.add(path)
            found = keypoint_payload(path)
            if found is None:
                unfollowed.append(parent)
            else:
                todo.append(found.get("metadata") or {})
    return Lineage(frozenset(trained), frozenset(validated), recorded, tuple(unfollowed))


def check_lineage(
    option: str,
    path: str | Path,
    payload: dict[str, Any],
    *,
    validation_subjects: Iterable[str],
    excluded_subjects: Iterable[str],
    train_subjects: Iterable[str] | None = None,
) -> Lineage:
    """Refuse (LineageError) a checkpoint given as ``option`` that trained on the run's
    validation or excluded subjects, was chosen on its excluded ones, records no training
    subjects, or (with ``train_subjects``) trained on a subject the run does not train on."""
    seen = lineage(payload)
    gone = (
        f" (not followed: {', '.join(seen.unfollowed)}, no longer readable)"
        if seen.unfollowed
        else ""
    )
    if not seen.recorded:
        raise LineageError(
            f"{option} {path}: the checkpoint does not say which subjects it trained on, so it "
            "may have seen this run's validation subjects; pass a checkpoint written by train"
        )
    held_out = set(validation_subjects) | set(excluded_subjects)
    leaked = sorted(seen.trained & held_out)
    if leaked:
        raise LineageError(
            f"{option} {path} trained on {leaked}{gone}, which this run validates on or "
            "excludes: it would leak them; pass a checkpoint trained without them"
        )
    chosen = sorted(seen.validated & set(excluded_subjects))
    if chosen:
        raise LineageError(
            f"{option} {path} was chosen on {chosen}{gone}, which this run excludes (its test "
            "fold); pass a checkpoint validated on other subjects"
        )
    if train_subjects is not None:
        unseen = sorted(seen.trained - set(train_subjects))
        if unseen:
            raise LineageError(
                f"{option} {path} trained on {unseen}{gone}, which this run does not train on; "
                "pass a checkpoint trained on this run's training subjects"
            )
    return seen
