"""The fold plan of crossval: the default plan's properties, its checks, restriction to the
subjects of a folder, and the JSON form of ``--folds FILE``."""

from __future__ import annotations

import csv
import json
from collections import Counter, defaultdict
from pathlib import Path

import pytest

from robot_retarget.evaluation.folds import (
    CONVERSIONS,
    DEFAULT_FOLDS,
    FoldError,
    FoldPlan,
    load_folds,
)


def _all_folds(plan: FoldPlan) -> list[tuple[str, ...]]:
    return [plan.test, *plan.cv]


def test_every_subject_is_in_exactly_one_fold() -> None:
    counts = Counter(s for fold in _all_folds(DEFAULT_FOLDS) for s in fold)
    assert set(counts) == set(CONVERSIONS)
    assert set(counts.values()) == {1}
    assert DEFAULT_FOLDS.subjects == tuple(sorted(CONVERSIONS))


def test_test_fold_is_disjoint_from_every_training_set() -> None:
    assert not set(DEFAULT_FOLDS.test) & set(DEFAULT_FOLDS.cv_subjects)
    for i, fold in enumerate(DEFAULT_FOLDS.cv):
        train = set(DEFAULT_FOLDS.train_subjects(i))
        assert not train & set(DEFAULT_FOLDS.test)
        assert not train & set(fold)
        assert train | set(fold) == set(DEFAULT_FOLDS.cv_subjects)


def test_every_fold_mixes_both_conversions() -> None:
    assert len(DEFAULT_FOLDS.test) == 2
    for fold in _all_folds(DEFAULT_FOLDS):
        assert {CONVERSIONS[s] for s in fold} == {"j31", "j43"}, fold


def test_conversions_and_frame_balance_match_the_manifest(shared_data_dir: Path) -> None:
    """CONVERSIONS agrees with the manifest's joint counts; CV folds are within 20 % of each
    other in frames, as the module docstring's table says."""
    with (shared_data_dir / "mocap" / "manifest.csv").open() as f:
        rows = list(csv.DictReader(f))
    frames: dict[str, int] = defaultdict(int)
    for row in rows:
        assert CONVERSIONS[row["subject"]] == f"j{row['joints']}", row["file"]
        frames[row["subject"]] += int(row["frames"])
    assert set(frames) == set(CONVERSIONS)
    per_fold = [sum(frames[s] for s in fold) for fold in DEFAULT_FOLDS.cv]
    assert per_fold == [13375, 12120, 14048]  # the docstring's numbers
    assert max(per_fold) / min(per_fold) < 1.2


@pytest.mark.parametrize(
    ("test", "cv", "match"),
    [
        ((), (("a",), ("b",)), "test fold is empty"),
        (("t",), (("a", "b"),), "at least 2 CV folds"),
        (("t",), (("a",), ()), r"\['cv-2'\] hold no subject"),
        (("t",), (("a", "t"), ("b",)), r"\['t'\] appear in more than one place"),
    ],
)
def test_malformed_plans_are_refused(
    test: tuple[str, ...], cv: tuple[tuple[str, ...], ...], match: str
) -> None:
    with pytest.raises(FoldError, match=match):
        FoldPlan(test, cv)


def test_restrict_keeps_the_folds_of_the_present_subjects() -> None:
    present = ["02", "03", "06", "07", "10", "12", "13", "14"]  # no 05, no 08
    plan = DEFAULT_FOLDS.restrict(present)
    assert plan.test == ("07", "13")
    assert plan.cv == (("02", "10"), ("03", "12"), ("06", "14"))


def test_unknown_subjects_are_an_error_not_a_guess() -> None:
    with pytest.raises(FoldError, match=r"\['99', 'me'\] of the data are in no fold") as info:
        DEFAULT_FOLDS.restrict([*DEFAULT_FOLDS.subjects, "me", "99"])
    assert info.value.subjects == ("99", "me")
    assert "--folds FILE" in str(info.value)


def test_a_fold_left_empty_is_an_error() -> None:
    with pytest.raises(FoldError, match=r"no subject of fold\(s\) \['test'\]"):
        DEFAULT_FOLDS.restrict(DEFAULT_FOLDS.cv_subjects)


def test_plan_file_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "folds.json"
    path.write_text(json.dumps(DEFAULT_FOLDS.to_json()))
    assert load_folds(path) == DEFAULT_FOLDS


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("{not json", "not JSON"),
        ("[1, 2]", "JSON object"),
        ('{"test": ["a"], "cv": "b"}', "lists of subject names"),
        ('{"test": ["a"], "cv": [["b"], [3]]}', "lists of subject names"),
        ('{"test": ["a"], "cv": [["b"], ["a"]]}', "more than one place"),
    ],
)
def test_bad_plan_files_name_the_file(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "folds.json"
    path.write_text(text)
    with pytest.raises(FoldError, match=match) as info:
        load_folds(path)
    assert info.value.path == str(path)


def test_missing_plan_file(tmp_path: Path) -> None:
    with pytest.raises(FoldError, match="cannot read the fold plan"):
        load_folds(tmp_path / "nope.json")
