"""Which subjects ``crossval`` trains on, validates on and keeps for the final test.

The plan is data (:data:`DEFAULT_FOLDS`, or a JSON file ``{"test": [...], "cv": [[...], ...]}``
passed as ``crossval --folds FILE``), not a rule applied at run time. The default covers the
ten subjects of the shared CMU set (frames at 120 fps, BVH conversion; ``manifest.csv``):

======= ====== ======= ===== ====================================
subject  clips  frames  conv  fold
======= ====== ======= ===== ====================================
02         10   12825  j31   cv-1
10          1     550  j43   cv-1   (cv-1: 13375 frames)
03          2     799  j31   cv-2
05         12    9557  j31   cv-2
12          3    1764  j43   cv-2   (cv-2: 12120 frames)
06          9    5647  j31   cv-3
08         11    3556  j31   cv-3
14          2    4845  j43   cv-3   (cv-3: 14048 frames)
07         12    4381  j31   test
13          8    5033  j43   test   (test: 9414 frames)
======= ====== ======= ===== ====================================

j31 is the 31-joint MotionBuilder-friendly conversion, j43 the 43-joint DAZ one (its subjects
share one skeleton).

The rule:

- **Test fold**: one subject per conversion, never trained on, validated on or used to pick
  anything while the cross-validation runs. Picked as the mid-sized subject of each conversion
  with the most clips (07: 12 walking clips; 13: 8 jumping / reaching clips), so the test row
  is neither one long take nor a single short clip, and its motion types (walking; jumping and
  reaching) also occur in the training subjects (02, 03, 08, 10, 12; 02, 14): the row measures
  new performers, not new kinds of motion.
- **CV folds**: every fold holds both conversions, so each scored clip has a human target of
  a different skeleton (the DAZ subjects share one skeleton; a DAZ-only fold would score
  only the robot targets), and frames are balanced as far as whole subjects allow
  (12120 to 14048 frames). With one DAZ subject in the test fold, three remain, so there are
  **three** CV folds, not four: a fourth fold would have had no DAZ subject.

A data folder holding only some of the plan's subjects uses the plan restricted to them
(:meth:`FoldPlan.restrict`; a fold left empty is an error). A folder holding any subject the
plan does not name is refused with :class:`FoldError` naming those subjects: their fold is
not guessed (pass a plan of your own with ``--folds FILE``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeGuard

from robot_retarget.errors import RetargetError

CONVERSIONS: Mapping[str, str] = {
    "02": "j31",
    "03": "j31",
    "05": "j31",
    "06": "j31",
    "07": "j31",
    "08": "j31",
    "10": "j43",
    "12": "j43",
    "13": "j43",
    "14": "j43",
}
"""BVH conversion of each subject of the shared set (j31 MotionBuilder, j43 DAZ)."""


class FoldError(RetargetError):
    """A fold plan is malformed or does not fit the data: names the subjects and what to do."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        subjects: Iterable[str] = (),
    ) -> None:
        self.path = None if path is None else str(path)
        self.subjects = tuple(subjects)
        super().__init__(f"{self.path}: {message}" if self.path is not None else message)


@dataclass(frozen=True)
class FoldPlan:
    """A held-out ``test`` fold and the cross-validation folds ``cv`` (subject names).

    Construction checks that every subject appears exactly once, the test fold is not empty
    and there are at least two CV folds, none empty.
    """

    test: tuple[str, ...]
    cv: tuple[tuple[str, ...], ...]

    def __post_init__(self) -> None:
        if not self.test:
            raise FoldError("the test fold is empty; name at least one held-out subject")
        if len(self.cv) < 2:
            raise FoldError(f"cross-validation needs at least 2 CV folds, got {len(self.cv)}")
        empty = [self.fold_name(i) for i, fold in enumerate(self.cv) if not fold]
        if empty:
            raise FoldError(f"CV fold(s) {empty} hold no subject")
        seen: dict[str, int] = {}
        for s in (*self.test, *(s for fold in self.cv for s in fold)):
            seen[s] = seen.get(s, 0) + 1
        repeated = sorted(s for s, n in seen.items() if n > 1)
        if repeated:
            raise FoldError(
                f"subject(s) {repeated} appear in more than one place; each subject belongs "
                "to exactly one fold",
                subjects=repeated,
            )

    @property
    def subjects(self) -> tuple[str, ...]:
        """Every subject of the plan, sorted."""
        return tuple(sorted((*self.test, *(s for fold in self.cv for s in fold))))

    @property
    def cv_subjects(self) -> tuple[str, ...]:
        """The subjects of all CV folds (what the final model trains on), sorted."""
        return tuple(sorted(s for fold in self.cv for s in fold))

    @staticmethod
    def fold_name(index: int) -> str:
        """``cv-1``, ``cv-2``, … for CV fold ``index`` (0-based)."""
        return f"cv-{index + 1}"

    def train_subjects(self, index: int) -> tuple[str, ...]:
        """The subjects CV fold ``index`` is trained on: the other CV folds (never the test
        fold), sorted."""
        return tuple(sorted(s for i, fold in enumerate(self.cv) if i != index for s in fold))

    def restrict(self, present: Iterable[str]) -> FoldPlan:
        """The plan for a data folder holding the subjects ``present``.

        Raises FoldError naming the subjects the plan does not know (their fold would be a
        guess) and when a fold would be left without subjects.
        """
        have = set(present)
        unknown = sorted(have - set(self.subjects))
        if unknown:
            raise FoldError(
                f"subject(s) {unknown} of the data are in no fold of the plan (known: "
                f"{list(self.subjects)}); pass --folds FILE with a plan naming every subject, "
                'e.g. {"test": ["a"], "cv": [["b", "c"], ["d", "e"]]}',
                subjects=unknown,
            )
        test = tuple(s for s in self.test if s in have)
        cv = tuple(tuple(s for s in fold if s in have) for fold in self.cv)
        missing = [
            name
            for name, fold in (("test", test), *((self.fold_name(i), f) for i, f in enumerate(cv)))
            if not fold
        ]
        if missing:
            raise FoldError(
                f"the data holds no subject of fold(s) {missing} (data subjects: "
                f"{sorted(have)}); add their clips or pass --folds FILE with a plan that fits",
                subjects=sorted(have),
            )
        return FoldPlan(test, cv)

    def to_json(self) -> dict[str, Any]:
        return {"test": list(self.test), "cv": [list(fold) for fold in self.cv]}

    @classmethod
    def from_json(cls, d: Mapping[str, Any], *, path: str | Path | None = None) -> FoldPlan:
        """A plan from ``{"test": [...], "cv": [[...], ...]}`` (subject names as strings)."""
        test, cv = d.get("test"), d.get("cv")
        if _names(test) and isinstance(cv, list) and all(_names(f) for f in cv):
            try:
                return cls(tuple(test), tuple(tuple(f) for f in cv))
            except FoldError as exc:
                raise FoldError(str(exc), path=path, subjects=exc.subjects) from exc
        raise FoldError(
            'a fold plan is {"test": ["07", "13"], "cv": [["02", "10"], ...]}: lists of '
            "subject names",
            path=path,
        )


def _names(value: object) -> TypeGuard[list[str]]:
    return isinstance(value, list) and all(isinstance(s, str) and s for s in value)


def load_folds(path: str | Path) -> FoldPlan:
    """The plan in a JSON file (see :meth:`FoldPlan.from_json`)."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except OSError as exc:
        raise FoldError(f"cannot read the fold plan ({exc.strerror})", path=p) from exc
    except json.JSONDecodeError as exc:
        raise FoldError(f"not JSON: {exc}", path=p) from exc
    if not isinstance(data, dict):
        raise FoldError('a fold plan is a JSON object {"test": [...], "cv": [...]}', path=p)
    return FoldPlan.from_json(data, path=p)


DEFAULT_FOLDS = FoldPlan(
    test=("07", "13"),
    cv=(("02", "10"), ("03", "05", "12"), ("06", "08", "14")),
)
"""The plan for the shared ten-subject set (see the module docstring for the rule)."""
