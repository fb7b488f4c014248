"""Train NKN or PMnet on a folder of BVH clips: the loop behind ``launch.py train``.

A run folder holds everything needed to inspect, evaluate or continue the run:

- ``config.json``: the :class:`TrainConfig` and the data hash (``--resume`` checks both);
- ``last.pt`` / ``best.pt``: checkpoints (robot_retarget.nn.checkpoint) with the model config,
  the skeleton set it was trained for (training subjects and robots), the data hash and the
  step; ``best.pt`` has the lowest validation score so far;
- ``trainer_state.pt``: step, discriminator weights, both optimisers, best score (for
  ``--resume``);
- ``log.csv`` and ``events.out.tfevents.*``: training losses and validation metrics.

Reproducible: batch n is a pure function of (seed, n) (WindowSampler) and the torch generator
is re-seeded from (seed, n) before each step, so a resumed run draws what the uninterrupted
run would have drawn.

Under ``torchrun --nproc-per-node N`` (the residual model) each rank trains on 1/N of the
same global batch with gradients averaged before every step (robot_retarget.nn.distributed);
rank 0 alone writes the run folder, which is the same for any N, so ``--resume`` works on
another world size.

Validation (every ``val_every`` steps) retargets fixed windows of the validation subjects onto
the other subjects' and the robots' skeletons and reports, on the heading-free local pose:
``recon`` and ``cycle`` (mean squared joint error / height², × 10³), ``ee``, ``contact`` and
``bone_deg`` against the source (as the ``eval`` metrics, robot_retarget.nn.retarget_losses),
``yaw_rate`` (mean |turning-rate error| against the source, rad/s: heading drift) and
``score`` = ``ee`` + ``contact`` + bone direction (rad) + ``cycle`` / 100 + ``yaw_rate``, which
picks ``best.pt``. With no validation subjects there is no validation and ``best.pt`` is the
last checkpoint. ``exclude_subjects`` (a held-out test fold, ``crossval``) are dropped from the
data before the split: neither trained nor validated on.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from robot_retarget.errors import ModelLoadError, RetargetError
from robot_retarget.nn.checkpoint import load_checkpoint, save_checkpoint
from robot_retarget.nn.dataset import (
    DEFAULT_FPS,
    DEFAULT_ROBOTS,
    DEFAULT_VALIDATION_SUBJECTS,
    DEFAULT_WINDOW_FRAMES,
    Augmentation,
    DatasetError,
    MotionDataset,
    WindowSampler,
    fit_features,
    load_dataset,
    robot_skeletons,
)
from robot_retarget.nn.device import device_problem
from robot_retarget.nn.distributed import DataParallel, DataParallelError
from robot_retarget.nn.features import compute_features, skeleton_height
from robot_retarget.nn.losses import end_effector_weights, reconstruction_loss, squared_error
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.nn.models.optimizers import LEARNING_RATE, make_optimizers
from robot_retarget.nn.models.registry import (
    build_discriminator,
    build_model,
    has_discriminator,
)
from robot_retarget.nn.models.training import check_loss_weights, training_step
from robot_retarget.nn.retarget_losses import bone_direction_loss, contact_loss, effector_loss
from robot_retarget.nn.run_folder import clear_run
from robot_retarget.nn.train_log import TrainLog

TRAINABLE_MODELS: tuple[str, ...] = ("nkn", "pmnet", "residual", "tdcn", "san")


@dataclass(frozen=True)
class TrainConfig:
    """Everything that defines a training run (stored in ``config.json``)."""

    model: str
    data_dir: str
    out_dir: str
    steps: int = 20000
    batch_size: int = 32
    window_frames: int = DEFAULT_WINDOW_FRAMES
    fps: float = DEFAULT_FPS
    validation_subjects: tuple[str, ...] = DEFAULT_VALIDATION_SUBJECTS
    robots: tuple[str, ...] = DEFAULT_ROBOTS
    val_every: int = 500
    val_batches: int = 4
    checkpoint_every: int = 500
    log_every: int = 25
    seed: int = 0
    device: str = "cpu"
    lr: float = LEARNING_RATE
    model_config: dict[str, Any] = field(default_factory=dict)
    discriminator_config: dict[str, Any] = field(default_factory=dict)
    same_skeleton_recon: float = 0.0
    loss_weights: dict[str, float] = field(default_factory=dict)
    max_frames: int | None = None
    cache_dir: str | None = None
    exclude_subjects: tuple[str, ...] = ()
    # Residual model: the share of denoising samples corrupted as a live position sender's
    # (robot_retarget.nn.live_noise) instead of with SAN's rotation noise.
    live_noise: float = 0.0

    def to_json(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["validation_subjects"] = list(self.validation_subjects)
        d["robots"] = list(self.robots)
        d["exclude_subjects"] = list(self.exclude_subjects)
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> TrainConfig:
        d = dict(d)
        d["validation_subjects"] = tuple(d["validation_subjects"])
        d["robots"] = tuple(d["robots"])
        d["exclude_subjects"] = tuple(d.get("exclude_subjects", ()))
        return cls(**d)


@dataclass(frozen=True)
class TrainProgress:
    """Reported to the caller's callback after logged steps and validations."""

    step: int
    total_steps: int
    elapsed_s: float
    losses: dict[str, float]
    validation: dict[str, float] | None = None


@dataclass(frozen=True)
class TrainResult:
    out_dir: Path
    best_path: Path
    last_path: Path
    steps: int
    best_score: float
    data_hash: str


class TrainError(RetargetError):
    """A run cannot start or resume as asked (names the run folder and what to do)."""

    def __init__(self, message: str, *, path: str | Path | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path is not None else message)


def check_networks(config: TrainConfig) -> None:
    """The model's and discriminator's settings, before any data is read: an option the
    network does not take, a value it cannot be built with (a negative size), a discriminator
    setting for a model trained without one, and a window shorter than the discriminator's
    patch (each had ended in a traceback, some after the data load)."""
    if config.discriminator_config and not has_discriminator(config.model):
        raise TrainError(
            f"--disc-config: {config.model} is trained without a discriminator; drop it"
        )
    probes: list[tuple[str, Callable[[], Any]]] = (
        [
            (
                "--disc-config",
                lambda: build_discriminator(config.model, **config.discriminator_config),
            )
        ]
        if has_discriminator(config.model)
        else []
    )
    if config.model != "san":  # SAN's encoders are sized by the data's skeletons: built later
        probes.insert(
            0, ("--model-config", lambda: build_model(config.model, **config.model_config))
        )
    for option, build in probes:
        try:
            net = build()
        except (TypeError, ValueError, RuntimeError) as exc:
            raise TrainError(
                f"{option}: {config.model} cannot be built with these settings ({exc})"
            ) from None
        need = getattr(net, "receptive_field", None)
        if option == "--disc-config" and need is not None and config.window_frames - 1 < need:
            raise TrainError(
                f"--window {config.window_frames}: {config.model}'s patch discriminator scores "
                f"{need} frame-to-frame steps at a time, so a window needs at least {need + 1} "
                f"frames; pass --window {need + 1} or more"
            )


def _seed_for(seed: int, step: int) -> int:
    return int(np.random.SeedSequence([seed, 3, step]).generate_state(1)[0])


def _device(name: str) -> torch.device:
    problem = device_problem(name)
    if problem is not None:
        raise TrainError(problem)
    return torch.device(name)


def _to(batch: RetargetBatch, device: torch.device) -> RetargetBatch:
    if device.type == "cpu":
        return batch
    real_q, real_root = batch.real_local_quats, batch.real_root_pos
    return RetargetBatch(
        src_local_quats=batch.src_local_quats.to(device),
        src_root_pos=batch.src_root_pos.to(device),
        src_offsets=batch.src_offsets.to(device),
        tgt_offsets=batch.tgt_offsets.to(device),
        same_skeleton=batch.same_skeleton.to(device),
        real_local_quats=None if real_q is None else real_q.to(device),
        real_root_pos=None if real_root is None else real_root.to(device),
    )


# Weight of the root-velocity term of same_skeleton_step, velocities in m/s and rad/s: a
# yaw-rate error of 0.1 rad/s (a 6°/s heading drift) then costs 0.1, a third of a typical
# pose reconstruction loss, so the integrated trajectory does not drift.
SAME_SKELETON_VEL_WEIGHT = 10.0


def same_skeleton_step(
    model: RetargetModel,
    batch: RetargetBatch,
    optimizer: torch.optim.Optimizer,
    weight: float,
    fps: float = DEFAULT_FPS,
) -> float:
    """Opt-in extra generator update (``same_skeleton_recon`` > 0), a deviation from PMnet's
    published losses, after NKN's square loss for B = A: on the samples whose target is their
    own skeleton, the output must reproduce the source — its local pose (PMnet's
    end-effector-weighted reconstruction loss, applied to the retargeted q_B instead of q_A)
    and its root velocities (squared error in m/s and rad/s, × SAME_SKELETON_VEL_WEIGHT).

    Without it, PMnet's q_B is tied to the source only through the perceptual loss on a
    jointly trained encoder (whose features can shrink to nothing), and its root movement only
    through the adversarial loss: in our runs validation A → A error grew while q_A's fell,
    and the integrated heading drifted. Returns the (unweighted) loss; 0 when the batch has
    no B = A sample.
    """
    same = batch.same_skeleton.to(torch.bool)
    if not bool(same.any()):
        return 0.0
    model.train()
    src = compute_features(batch.src_local_quats, batch.src_root_pos, batch.src_offsets)
    out = model.retarget_features(
        src, batch.src_root_pos[:, 0], batch.src_offsets, batch.tgt_offsets
    )
    joint_w = end_effector_weights().to(src.local_pos)
    pose = reconstruction_loss(out.features.local_pos, src.local_pos, joint_w)
    vel = squared_error(out.features.root_vel[:, 1:] * fps, src.root_vel[:, 1:] * fps)
    loss = (pose + SAME_SKELETON_VEL_WEIGHT * vel)[same].mean()
    optimizer.zero_grad(set_to_none=True)
    (weight * loss).backward()  # type: ignore[no-untyped-call]
    optimizer.step()
    return float(loss.detach())


def _pose_error(pos: torch.Tensor, ref: torch.Tensor, height: torch.Tensor) -> float:
    """Mean squared joint error over height², × 10³."""
    return float((((pos - ref) / height) ** 2).sum(-1).mean()) * 1e3


@torch.no_grad()
def validate(
    model: RetargetModel, batches: Sequence[RetargetBatch], fps: float = DEFAULT_FPS
) -> dict[str, float]:
    """Validation metrics on fixed batches (see the module docstring)."""
    model.eval()
    sums = {"recon": 0.0, "cycle": 0.0, "ee": 0.0, "contact": 0.0, "bone_deg": 0.0, "yaw_rate": 0.0}
    for b in batches:
        src = compute_features(b.src_local_quats, b.src_root_pos, b.src_offsets)
        init = b.src_root_pos[:, 0]
        h_src = skeleton_height(b.src_offsets)[:, None, None, None]
        same = model.retarget_features(src, init, b.src_offsets, b.src_offsets)
        out_b = model.retarget_features(src, init, b.src_offsets, b.tgt_offsets)
        back = model.retarget_features(out_b.features, init, b.tgt_offsets, b.src_offsets)

        sums["recon"] += _pose_error(same.features.local_pos, src.local_pos, h_src)
        sums["cycle"] += _pose_error(back.features.local_pos, src.local_pos, h_src)
        pos_b = out_b.features.local_pos
        sums["ee"] += float(
            effector_loss(src.local_pos, b.src_offsets, pos_b, b.tgt_offsets).mean()
        )
        sums["contact"] += float(
            contact_loss(src.local_pos, b.src_offsets, pos_b, b.tgt_offsets).mean()
        )
        bone = bone_direction_loss(src.local_pos, b.src_offsets, pos_b, b.tgt_offsets)
        sums["bone_deg"] += math.degrees(float(bone.mean()))
        # Turning rate is size-independent: the target should turn as the source does.
        dyaw = out_b.features.root_vel[:, 1:, 3] - src.root_vel[:, 1:, 3]
        sums["yaw_rate"] += float(dyaw.abs().mean()) * fps
    out = {k: v / len(batches) for k, v in sums.items()}
    out["score"] = (
        out["ee"]
        + out["contact"]
        + math.radians(out["bone_deg"])
        + out["cycle"] / 100.0
        + out["yaw_rate"]
    )
    return out


def _skeleton_set(train: MotionDataset, robots: dict[str, np.ndarray]) -> dict[str, Any]:
    skeletons: dict[str, Any] = {}
    for clip in train.clips:
        skeletons.setdefault(f"subject:{clip.subject}", clip.offsets)
    skeletons.update({f"robot:{name}": offs for name, offs in robots.items()})
    return skeletons


def train(
    config: TrainConfig,
    *,
    resume: bool = False,
    progress: Callable[[TrainProgress], None] | None = None,
    command: str = "",
    fresh: bool = False,
) -> TrainResult:
    """Run (or continue, with ``resume``) training as ``config`` says; returns where the
    checkpoints are. ``fresh``: a run already in the folder is deleted once the settings, the
    data, the model and its optimizer are accepted (``train --force``). Raises TrainError /
    DatasetError / ModelLoadError with what to change."""
    if config.model not in TRAINABLE_MODELS:
        raise TrainError(
            f"model {config.model!r} cannot be trained; choose {', '.join(TRAINABLE_MODELS)} "
            "(copy and copy-scaled have no parameters)"
        )
    try:
        check_loss_weights(config.model, config.loss_weights)
    except ValueError as exc:
        raise TrainError(f"--loss-weight: {exc}") from exc
    if not 0.0 <= config.live_noise <= 1.0:
        raise TrainError(f"--live-noise is a share of samples in [0, 1], got {config.live_noise}")
    if config.live_noise > 0.0 and config.model != "residual":
        raise TrainError(
            f"--live-noise trains the residual model's denoiser; {config.model} has none"
        )
    check_networks(config)
    out = Path(config.out_dir)
    cfg_path = out / "config.json"
    state_path = out / "trainer_state.pt"
    last_path = out / "last.pt"
    best_path = out / "best.pt"
    if not resume and not fresh and (last_path.exists() or state_path.exists()):
        raise TrainError(
            "run folder already holds a training run; pass --resume to continue it or choose "
            "another --out",
            path=out,
        )
    if resume and not (cfg_path.is_file() and state_path.is_file() and last_path.is_file()):
        raise TrainError(
            "nothing to resume: config.json, trainer_state.pt or last.pt is missing", path=out
        )
    dp = DataParallel.from_env(config.device)  # torchrun: this process's rank, else 1 of 1
    if dp.active:
        _check_data_parallel(config, dp)
    device = _device(dp.device(config.device))

    dataset = load_dataset(
        config.data_dir, fps=config.fps, max_frames=config.max_frames, cache_dir=config.cache_dir
    )
    if config.exclude_subjects:
        dataset = _exclude(dataset, config.exclude_subjects)
    train_set, val_set = dataset.split(config.validation_subjects)
    robots = robot_skeletons(config.robots)
    if resume:
        saved = json.loads(cfg_path.read_text())
        saved_cfg = TrainConfig.from_json(saved["config"])
        if saved_cfg.model != config.model or saved["data_hash"] != train_set.data_hash:
            raise TrainError(
                f"cannot resume: the run trained {saved_cfg.model} on data "
                f"{saved['data_hash'][:12]}…, now asked for {config.model} on "
                f"{train_set.data_hash[:12]}…; use the same --model and --data",
                path=out,
            )

    sampler = WindowSampler(
        train_set,
        window_frames=config.window_frames,
        batch_size=config.batch_size,
        robot_offsets=robots,
        real_motion=config.model == "nkn",
        native=config.model == "san",
        seed=config.seed,
    )
    # Validation: real skeletons only (other validation subjects and robots), no B = A.
    # No validation subjects: no validation, and best.pt is the last checkpoint.
    val_batches: list[RetargetBatch] = []
    if val_set.clips:
        val_sampler = WindowSampler(
            val_set,
            window_frames=config.window_frames,
            batch_size=config.batch_size,
            robot_offsets=robots,
            augmentation=Augmentation(
                global_scale=(1.0, 1.0), bone_scale=(1.0, 1.0), p_same=0.0, p_augment_source=0.0
            ),
            seed=config.seed,
        )
        val_batches = [
            _to(val_sampler.sample(i, stream=2), device) for i in range(config.val_batches)
        ]

    torch.manual_seed(config.seed)
    model_config = dict(config.model_config)
    if config.model == "san" and "domains" not in model_config:
        # One encoder per skeleton topology of the data (validation subjects' included: a
        # skeleton is not a performer, and an encoder for it must exist to score them).
        model_config["domains"] = native_domains(dataset)
    model = build_model(config.model, **model_config)
    disc = (
        build_discriminator(config.model, **config.discriminator_config)
        if has_discriminator(config.model)
        else None
    )
    start_step = 0
    best = math.inf
    if resume:
        model = load_checkpoint(last_path, expected_data_hash=train_set.data_hash).model
    else:
        feats, offsets = fit_features(sampler)
        model.fit_normalization(feats, offsets)
    model.to(device)
    if disc is not None:
        disc.to(device)
    dp.broadcast(model, disc)  # one starting point on every rank
    optimizers = make_optimizers(model, disc, lr=config.lr)
    dp.average_gradients_before_step(optimizers.generator)
    if resume:
        state = torch.load(state_path, map_location=device, weights_only=True)
        optimizers.generator.load_state_dict(state["generator_optimizer"])
        if disc is not None and optimizers.discriminator is not None:
            disc.load_state_dict(state["discriminator"])
            optimizers.discriminator.load_state_dict(state["discriminator_optimizer"])
        start_step = int(state["step"])
        best = float(state["best_score"])

    skeletons = _skeleton_set(train_set, robots)
    # Only now, with every setting, the data, the model and its optimizer accepted, is a run
    # replaced (--force) or the folder written: a refused run deletes nothing.
    if fresh and not resume and dp.is_main:
        clear_run(out)
    dp.barrier()  # every rank has checked the run folder before rank 0 writes into it
    if dp.is_main:
        out.mkdir(parents=True, exist_ok=True)
        cfg_path.write_text(
            json.dumps({"config": config.to_json(), "data_hash": train_set.data_hash}, indent=2)
        )

    def save(path: Path, step: int, val: dict[str, float] | None) -> None:
        if not dp.is_main:  # one copy of every file, written by rank 0
            return
        save_checkpoint(
            path,
            model,
            skeletons=skeletons,
            data_hash=train_set.data_hash,
            metadata={
                "step": step,
                "train_config": config.to_json(),
                "validation": val or {},
                "train_subjects": list(train_set.subjects),
                "validation_subjects": list(val_set.subjects),
                "command": command,
                "world_size": dp.world_size,
            },
        )

    def save_state(step: int) -> None:
        if not dp.is_main:
            return
        d_opt = optimizers.discriminator
        tmp = state_path.with_name(state_path.name + ".tmp")
        torch.save(
            {
                "step": step,
                "best_score": best,
                "discriminator": {} if disc is None else disc.state_dict(),
                "generator_optimizer": optimizers.generator.state_dict(),
                "discriminator_optimizer": {} if d_opt is None else d_opt.state_dict(),
            },
            tmp,
        )
        tmp.replace(state_path)

    started = time.monotonic()
    running: dict[str, float] = {}
    count = 0
    step = start_step
    with TrainLog(out) if dp.is_main else _NoLog() as log:
        if not resume and val_batches:
            val = validate(model, val_batches, config.fps)
            log.scalars(0, "val", val)
        for step in range(start_step + 1, config.steps + 1):
            torch.manual_seed(_seed_for(config.seed, step))
            batch = _to(dp.shard(sampler.sample(step)), device)
            extra = {}
            if config.same_skeleton_recon > 0.0:
                extra["same_recon"] = same_skeleton_step(
                    model, batch, optimizers.generator, config.same_skeleton_recon, config.fps
                )
            losses = dp.mean(  # the global batch's losses, the same on every rank
                {
                    **training_step(
                        model,
                        disc,
                        batch,
                        optimizers,
                        config.fps,
                        config.loss_weights,
                        live_noise=config.live_noise,
                    ),
                    **extra,
                }
            )
            for k, v in losses.items():
                running[k] = running.get(k, 0.0) + v
            count += 1
            if not math.isfinite(losses["total"]):
                raise TrainError(
                    f"training diverged at step {step} (loss {losses['total']}); lower --lr or "
                    "resume from the last checkpoint",
                    path=out,
                )
            val_now = bool(val_batches) and (step % config.val_every == 0 or step == config.steps)
            if step % config.log_every == 0 or val_now or step == config.steps:
                mean = {k: v / count for k, v in running.items()}
                log.scalars(step, "train", mean)
                running, count = {}, 0
                val_metrics = None
                if val_now:
                    val_metrics = validate(model, val_batches, config.fps)
                    log.scalars(step, "val", val_metrics)
                    if val_metrics["score"] < best:
                        best = val_metrics["score"]
                        save(best_path, step, val_metrics)
                log.flush()
                if progress is not None and dp.is_main:
                    progress(
                        TrainProgress(
                            step, config.steps, time.monotonic() - started, mean, val_metrics
                        )
                    )
            if step % config.checkpoint_every == 0 or step == config.steps:
                save(last_path, step, None)
                save_state(step)
    dp.barrier()
    if not best_path.exists() or not val_batches:  # no validation ran: best is the last
        save(best_path, step, None)
    return TrainResult(out, best_path, last_path, step, best, train_set.data_hash)


def native_domains(dataset: MotionDataset) -> dict[str, dict[str, Any]]:
    """Topology specs of the clips' own skeletons, by name (SAN's source domains)."""
    out: dict[str, dict[str, Any]] = {}
    for c in dataset.clips:
        if c.native is not None:
            out.setdefault(c.native.topology.name, c.native.topology.spec())
    return out


def _exclude(dataset: MotionDataset, subjects: Sequence[str]) -> MotionDataset:
    """``dataset`` without ``subjects`` (a held-out test fold: neither trained nor validated
    on); raises TrainError for a subject the data does not hold."""
    try:
        return dataset.without(subjects)
    except DatasetError as exc:
        raise TrainError(str(exc)) from exc


def _check_data_parallel(config: TrainConfig, dp: DataParallel) -> None:
    """What torchrun supports: models whose every step calls each optimiser unconditionally on
    every rank (a step some ranks skip would stall the gradient average)."""
    if config.model != "residual" or config.same_skeleton_recon > 0.0:
        raise DataParallelError(
            f"--model {config.model}"
            + (" with --same-skeleton-recon" if config.same_skeleton_recon > 0.0 else "")
            + " trains in one process only: its discriminator or extra update runs only when "
            "a shard holds certain samples; use --model residual, or run without torchrun",
            world_size=dp.world_size,
        )
    dp.check_batch_size(config.batch_size)


class _NoLog:
    """The log of ranks other than 0: rank 0 writes the one log."""

    def __enter__(self) -> _NoLog:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def scalars(self, step: int, split: str, values: dict[str, float]) -> None:
        return None

    def flush(self) -> None:
        return None


def load_run(out_dir: str | Path) -> tuple[TrainConfig, str]:
    """The config and data hash of a run folder."""
    path = Path(out_dir) / "config.json"
    if not path.is_file():
        raise ModelLoadError("no config.json: not a training run folder", path=path.parent)
    saved = json.loads(path.read_text())
    return TrainConfig.from_json(saved["config"]), str(saved["data_hash"])


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
