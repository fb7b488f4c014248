"""Subject-level cross-validation: the loop behind ``launch.py crossval``.

For a fold plan (robot_retarget.evaluation.folds) and each trainable model:

1. **CV folds.** For CV fold *k*: train on the other CV folds, with fold *k* as the run's
   validation subjects and the test fold excluded from the data (``TrainConfig.
   exclude_subjects``). The scored checkpoint is ``last.pt``, the final step: the fold is
   never used to pick it. (``best.pt``, picked by validation on fold *k* itself, is scored
   too and reported apart as ``MODEL@best-val``: an optimistic number, the gap between the
   two is what picking on the scored subjects is worth.) ``last.pt`` and the baselines
   ``copy`` and ``copy-scaled`` are scored on fold *k*'s clips by :func:`~robot_retarget.
   evaluation.runner.evaluate`, the code behind ``eval``.
2. **Summary.** Per model and metric: mean, sample standard deviation (ddof 1), min and max
   over the CV folds; per acceptance goal, the folds where it is met.
3. **Test row.** Train once on all CV subjects (no validation; ``last.pt``) and score that,
   and the baselines, on the test fold, which no step before has read.

``OUT/crossval.json`` holds the settings, the plan, per-fold scores, each training's command
line (``python launch.py train ...``, which reproduces the run), the git commit and the data
hash; it is rewritten after every training and every score, so ``resume=True`` continues where
a stopped run left off: finished scores are kept, a training with ``last.pt`` at the final step
is not repeated and an unfinished one continues from its last checkpoint.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shlex
import statistics
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robot_retarget.errors import RetargetError
from robot_retarget.evaluation.folds import DEFAULT_FOLDS, FoldPlan
from robot_retarget.evaluation.runner import (
    METRICS,
    EvalResult,
    EvalSettings,
    acceptance,
    evaluate,
)
from robot_retarget.nn.dataset import (
    DEFAULT_FPS,
    DEFAULT_ROBOTS,
    DEFAULT_WINDOW_FRAMES,
    MotionDataset,
    load_dataset,
    robot_skeletons,
)
from robot_retarget.nn.inference import load_model
from robot_retarget.nn.models.optimizers import LEARNING_RATE
from robot_retarget.nn.train import (
    TRAINABLE_MODELS,
    TrainConfig,
    TrainProgress,
    check_networks,
    train,
)

CROSSVAL_JSON = "crossval.json"
BASELINES: tuple[str, ...] = ("copy", "copy-scaled")
PEEK_SUFFIX = "@best-val"
"""Label suffix of a CV fold's ``best.pt`` (picked on the scored fold: optimistic)."""
TEST_FOLD = "test"
FORMAT = 1


class CrossvalError(RetargetError):
    """Cross-validation cannot run or resume as asked: names the folder and what to do."""

    def __init__(self, message: str, *, path: str | Path | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path is not None else message)


@dataclass(frozen=True)
class CrossvalConfig:
    """What to cross-validate and how each training runs (the ``train`` options)."""

    models: tuple[str, ...]
    data_dir: str
    out_dir: str
    steps: int
    robots: tuple[str, ...] = ("op3",)
    """Robots whose canonical skeletons are scoring targets (``eval --robot``)."""
    train_robots: tuple[str, ...] = DEFAULT_ROBOTS
    """Robots whose canonical skeletons are training targets (``train --robots``)."""
    batch_size: int = 32
    window_frames: int = DEFAULT_WINDOW_FRAMES
    fps: float = DEFAULT_FPS
    lr: float = LEARNING_RATE
    seed: int = 0
    val_every: int = 500
    checkpoint_every: int = 500
    model_config: dict[str, Any] = field(default_factory=dict)
    max_frames: int | None = None
    eval_seed: int = 0
    threads: int | None = None
    folds: FoldPlan = DEFAULT_FOLDS
    cache_dir: str | None = None
    device: str = "cpu"

    def settings_json(self) -> dict[str, Any]:
        """The settings that define the results (``resume`` insists they are unchanged)."""
        d = dataclasses.asdict(self)
        for key in ("out_dir", "cache_dir", "device", "threads", "folds"):
            d.pop(key)
        d["models"] = list(self.models)
        d["robots"] = list(self.robots)
        d["train_robots"] = list(self.train_robots)
        return d

    def train_config(
        self, model: str, out_dir: Path, validation: Sequence[str], exclude: Sequence[str]
    ) -> TrainConfig:
        return TrainConfig(
            model=model,
            data_dir=self.data_dir,
            out_dir=str(out_dir),
            steps=self.steps,
            batch_size=self.batch_size,
            window_frames=self.window_frames,
            fps=self.fps,
            validation_subjects=tuple(validation),
            robots=self.train_robots,
            val_every=self.val_every,
            checkpoint_every=self.checkpoint_every,
            seed=self.seed,
            device=self.device,
            lr=self.lr,
            model_config=dict(self.model_config),
            max_frames=self.max_frames,
            cache_dir=self.cache_dir,
            exclude_subjects=tuple(exclude),
        )


def train_command(config: TrainConfig, threads: int | None = None) -> str:
    """The ``python launch.py train ...`` line that runs ``config`` on its own."""
    args = [
        "--model", config.model, "--data", config.data_dir, "--out", config.out_dir,
        "--steps", str(config.steps), "--batch-size", str(config.batch_size),
        "--window", str(config.window_frames), "--fps", f"{config.fps:g}",
        "--val-subjects", ",".join(config.validation_subjects),
        "--exclude-subjects", ",".join(config.exclude_subjects),
        "--robots", ",".join(config.robots), "--val-every", str(config.val_every),
        "--checkpoint-every", str(config.checkpoint_every), "--seed", str(config.seed),
        "--lr", f"{config.lr:g}", "--device", config.device,
    ]  # fmt: skip
    for key, value in config.model_config.items():
        args += ["--model-config", f"{key}={json.dumps(value)}"]
    if config.max_frames is not None:
        args += ["--max-frames", str(config.max_frames)]
    if config.cache_dir is not None:
        args += ["--cache-dir", config.cache_dir]
    if threads is not None:
        args += ["--threads", str(threads)]
    return "python launch.py train " + shlex.join(args)


def git_state(repo: Path | None = None) -> dict[str, Any]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the checkout holding the package."""
    root = repo or Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        return {"commit": None, "dirty": None}
    return {"commit": commit, "dirty": bool(status.strip())}


Log = Callable[[str], None]
Progress = Callable[[str, TrainProgress], None]


def crossval(
    config: CrossvalConfig,
    *,
    resume: bool = False,
    log: Log | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Run the cross-validation (module docstring); returns the report also written to
    ``OUT/crossval.json``. Raises CrossvalError, FoldError, DatasetError, TrainError with what
    to change."""
    say = log or (lambda _text: None)
    bad = [m for m in config.models if m not in TRAINABLE_MODELS]
    if not config.models or bad:
        raise CrossvalError(
            f"cannot cross-validate model(s) {bad or '(none given)'}: crossval trains a model "
            f"per fold; choose from {', '.join(TRAINABLE_MODELS)} (copy and copy-scaled are "
            "always scored as baselines)"
        )
    if len(set(config.models)) != len(config.models):
        raise CrossvalError(f"model(s) named twice: {list(config.models)}")
    out = Path(config.out_dir)
    for model in config.models:  # before crossval.json is written: a refused run leaves none
        check_networks(config.train_config(model, out / model, (), ()))
    report_path = out / CROSSVAL_JSON
    dataset = load_dataset(
        config.data_dir, fps=config.fps, max_frames=config.max_frames, cache_dir=config.cache_dir
    )
    plan = config.folds.restrict(dataset.subjects)
    report = _start_report(config, plan, dataset, report_path, resume)
    out.mkdir(parents=True, exist_ok=True)
    _write(report_path, report)

    robots = robot_skeletons(config.robots)
    settings = EvalSettings(robots=config.robots, seed=config.eval_seed)
    entries = [*report["cv"], report["test"]]
    for entry in entries:
        fold, subjects = entry["fold"], tuple(entry["subjects"])
        clips = dataset.subset(subjects).clips
        scores: dict[str, Any] = entry["scores"]
        for name in BASELINES:
            if name not in scores:
                say(f"{fold}: scoring {name} on {', '.join(subjects)}")
                scores[name] = evaluate(load_model(name), clips, robots, settings).to_json()
                _write(report_path, report)
        for model in config.models:
            validation = () if fold == TEST_FOLD else subjects
            run_dir = out / model / fold
            tcfg = config.train_config(model, run_dir, validation, plan.test)
            expected = tuple(entry["train_subjects"])
            run = entry["runs"].setdefault(model, {})
            run.update({"out": str(run_dir), "train_command": train_command(tcfg, config.threads)})
            if model in scores and (fold == TEST_FOLD or model + PEEK_SUFFIX in scores):
                say(f"{fold}: {model} already trained and scored")
                continue
            started = time.monotonic()
            if _train_fold(tcfg, run, resume, say, progress, fold):
                run["train_s"] = run.get("train_s", 0.0) + (time.monotonic() - started)
                _write(report_path, report)
            scored = [("last.pt", model)]
            if fold != TEST_FOLD:
                scored.append(("best.pt", model + PEEK_SUFFIX))
            for filename, label in scored:
                loaded = load_model(str(run_dir / filename))
                trained_on = tuple(sorted(loaded.metadata.get("train_subjects", ())))
                if trained_on != expected or set(trained_on) & set(subjects):
                    raise CrossvalError(
                        f"{filename} was trained on {list(trained_on)}, but fold {fold} "
                        f"trains on {list(expected)} and scores {list(subjects)}; delete the "
                        "folder or choose another --out",
                        path=run_dir,
                    )
                if filename == "best.pt":
                    run["best_step"] = loaded.metadata.get("step")
                    run["best_val_score"] = loaded.metadata.get("validation", {}).get("score")
                else:
                    run["last_step"] = loaded.metadata.get("step")
                    run["data_hash"] = loaded.data_hash
                say(f"{fold}: scoring {label} on {', '.join(subjects)}")
                result = evaluate(loaded, clips, robots, settings)
                scores[label] = dataclasses.replace(result, model=label).to_json()
                _write(report_path, report)
    report["summary"] = summarize(report)
    report["finished"] = _now()
    _write(report_path, report)
    return report


def _start_report(
    config: CrossvalConfig,
    plan: FoldPlan,
    dataset: MotionDataset,
    path: Path,
    resume: bool,
) -> dict[str, Any]:
    settings = config.settings_json()
    if path.is_file():
        if not resume:
            raise CrossvalError(
                f"already holds a cross-validation ({CROSSVAL_JSON}); pass --resume to "
                "continue it or choose another --out",
                path=path.parent,
            )
        stored: dict[str, Any] = json.loads(path.read_text())
        changed = sorted(
            k
            for k in set(settings) | set(stored["settings"])
            if settings.get(k) != stored["settings"].get(k)
        )
        if changed or stored["folds"] != plan.to_json():
            what = changed or ["fold plan"]
            raise CrossvalError(
                f"cannot resume: {what} differ from the stored run "
                f"({ {k: stored['settings'].get(k) for k in changed} }); pass the same "
                "settings or choose another --out",
                path=path.parent,
            )
        if stored["data_hash"] != dataset.data_hash:
            raise CrossvalError(
                f"cannot resume: the data changed (hash {dataset.data_hash[:12]}…, stored "
                f"{stored['data_hash'][:12]}…); use the same --data or choose another --out",
                path=path.parent,
            )
        stored.pop("summary", None)
        stored.pop("finished", None)
        stored["resumed"] = [*stored.get("resumed", []), {"at": _now(), "git": git_state()}]
        return stored
    if path.parent.is_dir() and any(path.parent.iterdir()):
        raise CrossvalError(
            "folder is not empty and holds no crossval.json; choose an empty or new --out",
            path=path.parent,
        )

    def fold_entry(name: str, subjects: Sequence[str], train_on: Sequence[str]) -> dict[str, Any]:
        part = dataset.subset(subjects)
        return {
            "fold": name,
            "subjects": list(subjects),
            "train_subjects": list(train_on),
            "clips": len(part.clips),
            "frames": part.num_frames,
            "runs": {},
            "scores": {},
        }

    return {
        "format": FORMAT,
        "started": _now(),
        "git": git_state(),
        "data_dir": config.data_dir,
        "data_hash": dataset.data_hash,
        "settings": settings,
        "folds": plan.to_json(),
        "selection": "last.pt (the final step); the scored fold picks nothing. "
        f"MODEL{PEEK_SUFFIX} is best.pt picked on the scored fold itself (optimistic).",
        "spread": "std is the sample standard deviation over CV folds (ddof 1)",
        "cv": [
            fold_entry(plan.fold_name(i), subjects, plan.train_subjects(i))
            for i, subjects in enumerate(plan.cv)
        ],
        "test": fold_entry(TEST_FOLD, plan.test, plan.cv_subjects),
    }


def _train_fold(
    cfg: TrainConfig,
    run: dict[str, Any],
    resume: bool,
    say: Log,
    progress: Progress | None,
    fold: str,
) -> bool:
    """Train ``cfg`` unless its ``last.pt`` already reached the final step; True if it
    trained."""
    out = Path(cfg.out_dir)
    last = out / "last.pt"
    if last.is_file():
        step = load_model(str(last)).metadata.get("step")
        if step == cfg.steps:
            say(f"{fold}: {cfg.model} already trained ({cfg.steps} steps)")
            return False
    again = (out / "trainer_state.pt").is_file()
    if again and not resume:
        raise CrossvalError(
            "an unfinished training is here; pass --resume to continue it", path=out
        )
    say(f"{fold}: training {cfg.model} on {cfg.out_dir}" + (" (resumed)" if again else ""))
    result = train(
        cfg,
        resume=again,
        progress=None if progress is None else (lambda p: progress(fold, p)),
        command=run["train_command"],
    )
    run["trained_steps"] = result.steps
    return True


def summarize(report: dict[str, Any]) -> dict[str, Any]:
    """Per label: mean / std / min / max / n of each metric over the CV folds that scored it
    (also per target kind), the acceptance goals met per fold, and the test fold's metrics."""
    labels: list[str] = []
    for entry in report["cv"]:
        labels += [k for k in entry["scores"] if k not in labels]
    cv: dict[str, Any] = {}
    for label in labels:
        scored = [e["scores"][label] for e in report["cv"] if label in e["scores"]]
        cv[label] = {
            "folds": len(scored),
            "metrics": _spread([s["metrics"] for s in scored]),
            "by_target": {
                kind: _spread([s["by_target"][kind] for s in scored]) for kind in ("human", "robot")
            },
        }
    goals: dict[str, Any] = {}
    for label in labels:
        if label in BASELINES:
            continue
        met: dict[str, list[bool]] = {}
        for entry in report["cv"]:
            s = entry["scores"]
            if not all(k in s for k in (label, *BASELINES)):
                continue
            for check in acceptance([_result(s[k]) for k in (label, *BASELINES)], label):
                met.setdefault(check.goal, []).append(check.met)
        goals[label] = {goal: {"met": sum(v), "folds": len(v)} for goal, v in met.items()}
    test = {label: s["metrics"] for label, s in report["test"]["scores"].items()}
    return {"cv": cv, "acceptance": goals, "test": test}


def _result(d: dict[str, Any]) -> EvalResult:
    def nan(m: dict[str, float | None]) -> dict[str, float]:
        return {k: math.nan if v is None else float(v) for k, v in m.items()}

    return EvalResult(model=d["model"], metrics=nan(d["metrics"]))


def _spread(rows: Sequence[dict[str, float | None]]) -> dict[str, dict[str, float | None]]:
    out: dict[str, dict[str, float | None]] = {}
    for key, _ in METRICS:
        values = [float(v) for r in rows if (v := r.get(key)) is not None]
        if not values:
            out[key] = {"mean": None, "std": None, "min": None, "max": None, "n": 0}
            continue
        out[key] = {
            "mean": statistics.fmean(values),
            "std": statistics.stdev(values) if len(values) > 1 else 0.0,
            "min": min(values),
            "max": max(values),
            "n": len(values),
        }
    return out


def _fmt(v: float | None, digits: int = 3) -> str:
    return "n/a" if v is None else f"{v:.{digits}f}"


def format_report(report: dict[str, Any], *, markdown: bool = False) -> str:
    """The CV table (mean ± std, min–max per metric), the acceptance counts and the test
    row, from a report (a fresh one or a stored ``crossval.json``)."""
    summary = report.get("summary") or summarize(report)
    labels = list(summary["cv"])
    cv_rows = []
    for key, header in METRICS:
        cells = []
        for label in labels:
            m = summary["cv"][label]["metrics"][key]
            cells.append(
                "n/a"
                if m["mean"] is None
                else f"{_fmt(m['mean'])} ± {_fmt(m['std'])} ({_fmt(m['min'])}–{_fmt(m['max'])})"
            )
        cv_rows.append([header, *cells])
    cv_headers = ["metric", *(f"{x} [{summary['cv'][x]['folds']}]" for x in labels)]
    test_labels = list(summary["test"])
    test_rows = [
        [header, *(_fmt(summary["test"][x].get(key)) for x in test_labels)]
        for key, header in METRICS
    ]
    folds = ", ".join(f"{e['fold']}: {'+'.join(e['subjects'])}" for e in report["cv"])
    test = "+".join(report["test"]["subjects"])
    parts = [
        f"cross-validation over {len(report['cv'])} subject folds ({folds}); "
        "mean ± std (min–max) over folds, [folds scored]; lower is better",
        _table(cv_headers, cv_rows, markdown),
    ]
    if summary["acceptance"]:
        lines = ["acceptance goals (folds where met):"]
        for label, goals in summary["acceptance"].items():
            text = "; ".join(f"{g}: {v['met']}/{v['folds']}" for g, v in goals.items())
            lines.append(f"  {label}: {text}")
        parts.append("\n".join(lines))
    parts.append(f"test fold {test} (trained on {'+'.join(report['test']['train_subjects'])}):")
    parts.append(
        _table(["metric", *test_labels], test_rows, markdown) if test_labels else "not scored yet"
    )
    return "\n\n".join(parts)


def _table(headers: Sequence[str], rows: Sequence[Sequence[str]], markdown: bool) -> str:
    if markdown:
        lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
        return "\n".join([*lines, *("| " + " | ".join(r) + " |" for r in rows)])
    widths = [max([len(h), *(len(r[i]) for r in rows)]) for i, h in enumerate(headers)]
    out = ["  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True))]
    out += ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(out)


def _write(path: Path, report: dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(report, indent=2) + "\n")
    tmp.replace(path)


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
