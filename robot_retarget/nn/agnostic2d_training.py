"""Training the character-agnostic 2D model (``train --model agnostic2d``).

Data: the project's CMU clips (training subjects only; robot_retarget.nn.dataset), each batch
a set of windows, each window performed by a randomly proportioned skeleton (per-bone scales,
left/right symmetric) and seen by *two* random virtual cameras (azimuth 0–360°, elevation,
distance, focal length: robot_retarget.keypoints.synthetic.CameraRange) with estimator-like
noise, dropouts and hidden face points. Targets: the window's canonical local rotations, the
root's turned into each camera's heading frame.

Loss per view: rotation matrices (‖R − R*‖²) + global bone directions on the reference
skeleton (what the optimizer follows) + the paper's triplet loss (margin 0.3) on the
time-averaged motion code: the two views of a window closer than two different windows. Each
batch is run causally (stream) or with whole-window static pooling (convert), at random.
Optimiser: AMSGrad (the paper's). Checkpoints (``best.pt`` by validation bone-direction error on
the validation subjects through fixed cameras, ``last.pt``) and their numpy runtimes
(``best.npz``, ``last.npz``), ``log.csv``.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn import functional as nnf

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ModelLoadError, RetargetError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.normalize import normalize_sequences
from robot_retarget.keypoints.synthetic import CameraRange, EstimatorNoise, render_keypoints
from robot_retarget.keypoints.virtual_camera import VirtualCamera, heading_quat
from robot_retarget.nn.checkpoint import foreign_file, unreadable_reason
from robot_retarget.nn.dataset import (
    Augmentation,
    Clip,
    MotionDataset,
    augment_offsets,
    leg_length,
    load_dataset,
)
from robot_retarget.nn.device import device_problem
from robot_retarget.nn.keypoint_lineage import check_lineage
from robot_retarget.nn.keypoint_teacher import KeypointTeacher, TeacherAnswer
from robot_retarget.nn.models.agnostic2d import Agnostic2D, rotation_6d_to_matrix
from robot_retarget.nn.models.registry import KEYPOINT_MODELS
from robot_retarget.nn.motion_augmentation import MotionAugmentation, augmented_window
from robot_retarget.nn.run_folder import clear_run
from robot_retarget.npz_errors import is_numpy_archive
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime, save_agnostic2d
from robot_retarget.skeleton.canonical import CANONICAL_PARENTS, Joint, default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

CHECKPOINT_FORMAT = "robot-retarget-keypoint-model"
CHECKPOINT_VERSION = 1
TRIPLET_MARGIN = 0.3  # the paper's α
VALIDATION_ELEVATIONS_DEG = (0.0, 15.0, 30.0)
_SKELETON_AUGMENTATION = Augmentation(global_scale=(0.85, 1.15), bone_scale=(0.85, 1.15))


class KeypointTrainError(RetargetError):
    """Training the keypoint model cannot go on as asked (names what to change)."""


@dataclass(frozen=True)
class KeypointTrainConfig:
    data_dir: str
    out_dir: str
    steps: int = 6000
    batch_size: int = 24
    window_frames: int = 64
    fps: float = 30.0
    validation_subjects: tuple[str, ...] = ("06", "08", "12")
    exclude_subjects: tuple[str, ...] = ()  # neither trained nor validated on (a test fold)
    val_every: int = 500
    seed: int = 0
    lr: float = 1e-3
    triplet_weight: float = 0.1
    direction_weight: float = 1.0
    limb_weight: float = 0.0  # extra weight on the scored segments' bones (limbs, spine)
    model_config: dict[str, Any] = field(default_factory=dict)
    max_frames: int | None = None
    cache_dir: str | None = None
    augment: MotionAugmentation = field(default_factory=MotionAugmentation)
    device: str = "cpu"  # "cuda" where a GPU is lent; batches are still rendered on the CPU
    loader_workers: int = 0  # processes rendering batches ahead of the training step
    # Share of batches run causally, as ``stream`` runs the model (the rest with whole-window
    # static pooling); None: half. A centred model runs every batch whole-window.
    causal_probability: float | None = None
    init_from: str | None = None  # a keypoint checkpoint whose weights start the run
    # Keypoint checkpoints whose averaged answer is a second target (robot_retarget.nn.
    # keypoint_teacher), weighted distill_weight against the ground truth's 1 − distill_weight.
    distill_from: tuple[str, ...] = ()
    distill_weight: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 <= self.distill_weight <= 1.0:
            raise KeypointTrainError(
                f"--distill-weight {self.distill_weight} is not in [0, 1]: pass the teacher's "
                "share of the target, e.g. 0.5"
            )
        if self.causal_probability is not None and not 0.0 <= self.causal_probability <= 1.0:
            raise KeypointTrainError(
                f"--causal-probability {self.causal_probability} is not in [0, 1]: pass a share of "
                "batches, e.g. 1 (every batch causal)"
            )


@dataclass(frozen=True)
class RenderedBatch:
    """Features (N, T, 51) and target local rotations (N, T, 22, 4), float32 tensors."""

    features: torch.Tensor
    targets: torch.Tensor


def _fk_window(
    clip: Clip, start: int, frames: int, offsets: FloatArray
) -> tuple[FloatArray, FloatArray]:
    sl = slice(start, start + frames)
    root = clip.root_pos[sl] * (leg_length(offsets) / leg_length(clip.offsets))
    skel = Skeleton(clip.skeleton.names, clip.skeleton.parents, offsets)
    return forward_kinematics(skel, clip.local_quats[sl], root)


def render_window(
    clip: Clip,
    start: int,
    frames: int,
    offsets: FloatArray,
    camera: VirtualCamera,
    rng: np.random.Generator,
    noise: EstimatorNoise,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pixels (T, 17, 2), visibility (T, 17) and target rotations (T, 22, 4) of one view."""
    pos, glob = _fk_window(clip, start, frames, offsets)
    height = clip.height_m * leg_length(offsets) / leg_length(clip.offsets)
    px, _conf, valid = render_keypoints(pos, glob, height, camera, rng, noise)
    target = np.array(clip.local_quats[start : start + frames])
    target[:, 0] = quat.mul(heading_quat(camera.azimuth_rad), target[:, 0])
    return px, valid.astype(np.float64), target


class TwoViewSampler:
    """Batches of windows, each rendered through two random cameras (see the module docstring);
    batch ``step`` is a pure function of (seed, step)."""

    def __init__(
        self,
        dataset: MotionDataset,
        *,
        window_frames: int,
        batch_size: int,
        seed: int = 0,
        cameras: CameraRange | None = None,
        noise: EstimatorNoise | None = None,
        augment: MotionAugmentation | None = None,
    ) -> None:
        self.augment = augment or MotionAugmentation()
        # A window at the fastest speed reads this many source frames.
        need = self.augment.source_frames(window_frames, self.augment.speed[1])
        self.clips = [c for c in dataset.clips if c.num_frames >= need]
        self._donors = [c for c in dataset.clips if c.num_frames >= window_frames]
        if not self.clips:
            raise KeypointTrainError(f"no training clip has {need} frames; use --window")
        self.window_frames = window_frames
        self.batch_size = batch_size
        self.seed = seed
        self.cameras = cameras or CameraRange()
        self.noise = noise or EstimatorNoise()
        starts = np.array([c.num_frames - need + 1 for c in self.clips], dtype=np.float64)
        self._p = starts / starts.sum()

    def sample(self, step: int) -> RenderedBatch:
        """Views A (first half) and B (second half) of ``batch_size`` windows."""
        return _to_tensors(*self.sample_arrays(step))

    def sample_arrays(self, step: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`sample` as float32 arrays (features, targets): what a loader process returns."""
        rng = np.random.default_rng([self.seed, step])
        views: list[list[tuple[FloatArray, FloatArray, FloatArray]]] = [[], []]
        for _ in range(self.batch_size):
            clip = self.clips[int(rng.choice(len(self.clips), p=self._p))]
            if self.augment.active:
                # One motion per window, the same in both views (the triplet loss's positive).
                clip = augmented_window(
                    clip, self.window_frames, rng, self.augment, donors=self._donors
                )
                start = 0
            else:  # the batches of checkpoints trained before augmentation existed
                start = int(rng.integers(0, clip.num_frames - self.window_frames + 1))
            for view in views:
                offsets = augment_offsets(clip.offsets, rng, _SKELETON_AUGMENTATION)
                camera = self.cameras.sample(rng)
                view.append(
                    render_window(clip, start, self.window_frames, offsets, camera, rng, self.noise)
                )
        return _stack(views[0] + views[1])


def _stack(
    items: Sequence[tuple[FloatArray, FloatArray, FloatArray]],
) -> tuple[np.ndarray, np.ndarray]:
    px = np.stack([i[0] for i in items])
    valid = np.stack([i[1] for i in items]) > 0.5
    feats = normalize_sequences(px, valid)
    targets = np.stack([i[2] for i in items])
    return feats.astype(np.float32), targets.astype(np.float32)


def _to_tensors(feats: np.ndarray, targets: np.ndarray) -> RenderedBatch:
    return RenderedBatch(torch.from_numpy(feats), torch.from_numpy(targets))


def _on(batch: RenderedBatch, device: torch.device) -> RenderedBatch:
    if device.type == "cpu":
        return batch
    return RenderedBatch(
        batch.features.to(device, non_blocking=True), batch.targets.to(device, non_blocking=True)
    )


_LOADER_SAMPLER: TwoViewSampler | None = None  # a loader process's sampler (inherited by fork)


def _loader_sample(step: int) -> tuple[np.ndarray, np.ndarray]:
    assert _LOADER_SAMPLER is not None
    return _LOADER_SAMPLER.sample_arrays(step)


@contextmanager
def rendered_batches(
    sampler: TwoViewSampler, steps: range, workers: int
) -> Iterator[Iterator[RenderedBatch]]:
    """The batches of ``steps`` in order, rendered by ``workers`` forked processes ahead of the
    training step (0: in this process). A batch is a pure function of (seed, step), so the
    batches, and the training run, are the same whatever the number of workers."""
    if workers <= 0:
        yield (sampler.sample(step) for step in steps)
        return
    global _LOADER_SAMPLER
    _LOADER_SAMPLER = sampler  # read by the forked processes, never pickled
    try:
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            arrays = pool.imap(_loader_sample, steps, chunksize=1)
            yield (_to_tensors(f, t) for f, t in arrays)
    finally:
        _LOADER_SAMPLER = None  # the sampler (and its clips) are not kept after training


def validation_batch(
    dataset: MotionDataset, window_frames: int, seed: int = 1234, windows_per_view: int = 16
) -> RenderedBatch:
    """Fixed windows of the validation subjects through fixed cameras at the validation
    elevations (azimuths 22.5° + k·45°, 4 m, 1000 px) with estimator-like noise."""
    rng = np.random.default_rng(seed)
    clips = [c for c in dataset.clips if c.num_frames >= window_frames]
    if not clips:
        raise KeypointTrainError(f"no validation clip has {window_frames} frames")
    items = []
    for e in VALIDATION_ELEVATIONS_DEG:
        for k in range(windows_per_view):
            clip = clips[int(rng.integers(len(clips)))]
            start = int(rng.integers(0, clip.num_frames - window_frames + 1))
            cam = VirtualCamera(math.radians(22.5 + 45.0 * (k % 8)), math.radians(e), 4.0, 1000.0)
            items.append(
                render_window(clip, start, window_frames, clip.offsets, cam, rng, EstimatorNoise())
            )
    return _to_tensors(*_stack(items))


# ------------------------------------------------------------------------------ losses
_REF = default_canonical_skeleton()
_CHILDREN = [j for j in range(1, len(CANONICAL_PARENTS))]
_BONE_DIRS = torch.tensor(
    _REF.offsets[1:] / np.maximum(np.linalg.norm(_REF.offsets[1:], axis=1, keepdims=True), 1e-9),
    dtype=torch.float32,
)
_HAS_LENGTH = torch.tensor(np.linalg.norm(_REF.offsets[1:], axis=1) > 1e-6)
# Bones of the segments eval-robot scores (upper arms, forearms, thighs, shins; the spine for
# the torso), as indices into bone_directions' output (child joint − 1).
_SCORED_BONES = torch.tensor(
    [
        int(Joint[n]) - 1
        for n in ("LeftForeArm", "LeftHand", "RightForeArm", "RightHand", "LeftLeg",
                  "LeftFoot", "RightLeg", "RightFoot", "Spine1", "Spine2", "Neck")
    ]
)  # fmt: skip


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    w, x, y, z = q.unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
            2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
            2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    ).reshape(*q.shape[:-1], 3, 3)  # fmt: skip


def bone_directions(local: torch.Tensor) -> torch.Tensor:
    """Local rotation matrices (…, 22, 3, 3) → global directions (…, 21, 3) of the reference
    skeleton's bones (each joint's offset turned by its parent's global rotation)."""
    glob: list[torch.Tensor] = []
    for j, p in enumerate(CANONICAL_PARENTS):
        glob.append(local[..., j, :, :] if p < 0 else glob[p] @ local[..., j, :, :])
    parents = torch.stack([glob[CANONICAL_PARENTS[c]] for c in _CHILDREN], dim=-3)
    return (parents @ _BONE_DIRS.to(local)[..., None])[..., 0]


def direction_error_deg(pred: torch.Tensor, target: torch.Tensor) -> float:
    """Mean angle (°) between predicted and target bone directions (bones with a length)."""
    cos = (bone_directions(pred) * bone_directions(target)).sum(-1).clamp(-1.0, 1.0)
    return float(torch.rad2deg(torch.acos(cos[..., _HAS_LENGTH])).mean())


def losses(
    model: Agnostic2D,
    batch: RenderedBatch,
    causal: bool,
    cfg: KeypointTrainConfig,
    teacher: TeacherAnswer | None = None,
) -> dict[str, torch.Tensor]:
    """The loss terms (module docstring); with ``teacher``, each of the rotation, direction and
    limb terms is ``1 − cfg.distill_weight`` of its distance to the truth plus
    ``cfg.distill_weight`` of its distance to the teacher's answer (``total`` weighs the blend;
    the ``rotation``, ``direction`` and ``limbs`` entries stay the truth's, the ``teacher_*``
    entries are the teacher's)."""
    d6, motion = model(batch.features, causal)
    pred = rotation_6d_to_matrix(d6)
    pred_dirs = bone_directions(pred)
    target = quat_to_matrix(batch.targets)
    truth = _distances(pred, pred_dirs, target, bone_directions(target))
    rot, dirs, limbs = truth
    parts: dict[str, torch.Tensor] = {}
    if teacher is not None:
        taught = _distances(pred, pred_dirs, teacher.matrices, teacher.directions)
        parts = dict(
            zip(("teacher_rotation", "teacher_direction", "teacher_limbs"), taught, strict=True)
        )
        w = cfg.distill_weight
        rot, dirs, limbs = ((1 - w) * a + w * b for a, b in zip(truth, taught, strict=True))
    code = nnf.normalize(motion.mean(dim=-1), dim=-1)
    half = code.shape[0] // 2
    a, p = code[:half], code[half:]
    n = torch.roll(p, 1, dims=0)
    triplet = nnf.relu((a - p).norm(dim=-1) - (a - n).norm(dim=-1) + TRIPLET_MARGIN).mean()
    total = (
        rot + cfg.direction_weight * dirs + cfg.limb_weight * limbs + cfg.triplet_weight * triplet
    )
    return {
        "total": total,
        "rotation": truth[0],
        "direction": truth[1],
        "limbs": truth[2],
        "triplet": triplet,
        **parts,
    }


def _distances(
    pred: torch.Tensor, pred_dirs: torch.Tensor, target: torch.Tensor, target_dirs: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Mean squared distances of rotation matrices, of bone directions (bones with a length)
    and of the scored bones' directions."""
    rot = ((pred - target) ** 2).sum((-1, -2)).mean()
    per_bone = ((pred_dirs - target_dirs) ** 2).sum(-1)
    return rot, per_bone[..., _HAS_LENGTH].mean(), per_bone[..., _SCORED_BONES].mean()


# ------------------------------------------------------------------------------ files
def save_keypoint_checkpoint(
    path: Path, model: Agnostic2D, *, data_hash: str, metadata: dict[str, Any]
) -> Path:
    """``path`` (.pt: config + weights + provenance, plain data) and its runtime (.npz)."""
    payload = {
        "format": CHECKPOINT_FORMAT,
        "version": CHECKPOINT_VERSION,
        "model": model.name,
        "config": model.config(),
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "data_hash": data_hash,
        "metadata": metadata,
    }
    tmp = path.with_name(path.name + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, path)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    runtime = Agnostic2DRuntime(
        model.export_weights(),
        name=path.stem,
        checkpoint_sha256=digest,
        data_hash=data_hash,
        metadata=metadata,
    )
    npz_tmp = path.with_name(f".{path.stem}.npz.tmp")
    save_agnostic2d(runtime, npz_tmp)
    os.replace(npz_tmp, path.with_suffix(".npz"))
    return path


def load_keypoint_checkpoint(path: str | Path) -> tuple[Agnostic2D, dict[str, Any]]:
    """The model (eval mode) and the checkpoint's payload; ModelLoadError says what is wrong."""
    source = Path(path)
    foreign = foreign_file(source)
    if foreign is not None:
        raise ModelLoadError(foreign, path=source)
    try:
        payload = torch.load(source, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise ModelLoadError("no such keypoint checkpoint", path=source) from None
    except Exception as exc:  # torch raises many types for foreign files
        raise ModelLoadError(
            f"not a readable checkpoint ({unreadable_reason(exc)})", path=source
        ) from exc
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise ModelLoadError(f"not a {CHECKPOINT_FORMAT} checkpoint", path=source)
    config = dict(payload["config"])
    config["dilations"] = tuple(config.get("dilations", (1, 2, 4, 8)))
    name = str(payload.get("model", Agnostic2D.name))
    if name not in KEYPOINT_MODELS:
        raise ModelLoadError(f"unknown keypoint model {name!r}", path=source, model=name)
    model = KEYPOINT_MODELS[name](**config)
    model.load_state_dict(payload["state_dict"])
    model.eval()
    return model, payload


# ------------------------------------------------------------------------------ loop
@dataclass(frozen=True)
class KeypointProgress:
    step: int
    total_steps: int
    losses: dict[str, float]
    validation: dict[str, float] | None
    elapsed_s: float


def train_agnostic2d(
    cfg: KeypointTrainConfig,
    *,
    progress: Callable[[KeypointProgress], None] | None = None,
    command: str = "",
    fresh: bool = False,
) -> dict[str, Any]:
    """Train, validate, checkpoint (see the module docstring); returns a JSON-able summary.
    ``fresh``: a run already in the folder is deleted once the settings, the data, the model
    and its optimizer are accepted."""
    # The model first: a refused --init-from or option costs no data loading and no files.
    torch.manual_seed(cfg.seed)
    model, start = _initial_model(cfg)
    teacher = KeypointTeacher.load(cfg.distill_from, fps=cfg.fps) if cfg.distill_from else None
    if model.centered and cfg.causal_probability is not None:
        raise KeypointTrainError(
            f"--causal-probability {cfg.causal_probability}: a centred model looks ahead and "
            "never runs causally; drop the option for centred models"
        )
    causal_share = 0.5 if cfg.causal_probability is None else cfg.causal_probability
    out = Path(cfg.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    dataset = load_dataset(
        cfg.data_dir, fps=cfg.fps, max_frames=cfg.max_frames, cache_dir=cfg.cache_dir
    )
    if cfg.exclude_subjects:
        dataset = dataset.without(cfg.exclude_subjects)
    train_set, val_set = dataset.split(cfg.validation_subjects)
    if start is not None:
        check_lineage(
            "--init-from",
            str(cfg.init_from),
            start,
            validation_subjects=val_set.subjects,
            excluded_subjects=cfg.exclude_subjects,
        )
    if teacher is not None:
        teacher.check_subjects(
            train_subjects=train_set.subjects,
            validation_subjects=val_set.subjects,
            excluded_subjects=cfg.exclude_subjects,
        )
    device = _device(cfg.device)
    model = model.to(device)
    if teacher is not None:
        teacher.to(device)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr, amsgrad=True)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(
        opt, T_max=max(cfg.steps, 1), eta_min=cfg.lr * 0.05
    )
    sampler = TwoViewSampler(
        train_set,
        window_frames=cfg.window_frames,
        batch_size=cfg.batch_size,
        seed=cfg.seed,
        augment=cfg.augment,
    )
    val_batch = _on(validation_batch(val_set, cfg.window_frames), device)
    meta_base = {
        "train_subjects": list(train_set.subjects),
        "validation_subjects": list(val_set.subjects),
        "excluded_subjects": list(cfg.exclude_subjects),
        "command": command,
        "receptive_field_frames": model.receptive_field,
        "fps": cfg.fps,
        **({"init_from": cfg.init_from} if cfg.init_from else {}),
        **(
            {"distilled_from": teacher.sources, "distill_weight": cfg.distill_weight}
            if teacher is not None
            else {}
        ),
    }
    # Only now, with the settings, the data, the model and its optimizer accepted, is a run
    # replaced (--force) or the folder written: a refused run deletes nothing.
    if fresh:
        clear_run(out)
    (out / "config.json").write_text(json.dumps({**asdict(cfg), "command": command}, indent=2))
    log_path = out / "log.csv"
    with log_path.open("w", newline="") as fh:
        csv.writer(fh).writerow(["step", "elapsed_s", "split", "metric", "value"])
    best = math.inf
    best_val: dict[str, float] = {}
    # A centred model runs on whole clips only (convert): it is chosen by that error.
    selection = "direction_error_deg_" + ("clip" if model.centered else "causal")
    t0 = time.monotonic()
    rng = np.random.default_rng([cfg.seed, 99])
    with rendered_batches(sampler, range(1, cfg.steps + 1), cfg.loader_workers) as batches:
        for step, cpu_batch in enumerate(batches, start=1):
            model.train()
            batch = _on(cpu_batch, device)
            causal = bool(rng.random() < causal_share) and not model.centered
            answer = None if teacher is None else teacher.answer(batch.features)
            parts = losses(model, batch, causal=causal, cfg=cfg, teacher=answer)
            opt.zero_grad()
            parts["total"].backward()  # type: ignore[no-untyped-call]
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            sched.step()
            scalars = {k: float(v.detach()) for k, v in parts.items()}
            val: dict[str, float] | None = None
            if step % cfg.val_every == 0 or step == cfg.steps:
                val = _validate(model, val_batch)
                meta = {**meta_base, "step": step, "validation": val}
                save_keypoint_checkpoint(
                    out / "last.pt", model, data_hash=train_set.data_hash, metadata=meta
                )
                if val[selection] < best:
                    best = val[selection]
                    best_val = val
                    save_keypoint_checkpoint(
                        out / "best.pt", model, data_hash=train_set.data_hash, metadata=meta
                    )
            elapsed = time.monotonic() - t0
            with log_path.open("a", newline="") as fh:
                w = csv.writer(fh)
                for k, v in scalars.items():
                    w.writerow([step, f"{elapsed:.1f}", "train", k, f"{v:.6g}"])
                for k, v in (val or {}).items():
                    w.writerow([step, f"{elapsed:.1f}", "val", k, f"{v:.6g}"])
            if progress is not None:
                progress(KeypointProgress(step, cfg.steps, scalars, val, elapsed))
    return {
        "out": str(out),
        "best": str(out / "best.pt"),
        "last": str(out / "last.pt"),
        "steps": cfg.steps,
        "best_validation": best_val,
        "data_hash": train_set.data_hash,
    }


def _initial_model(cfg: KeypointTrainConfig) -> tuple[Agnostic2D, dict[str, Any] | None]:
    """A new model of ``cfg.model_config``, or ``cfg.init_from``'s weights and architecture
    (fine-tuning: a ``--model-config`` that disagrees with the checkpoint's is refused) and
    that checkpoint's contents (None for a new model)."""
    config = dict(cfg.model_config)
    if "dilations" in config:
        config["dilations"] = tuple(config["dilations"])
    if cfg.init_from is None:
        return KEYPOINT_MODELS[Agnostic2D.name](**config), None
    if is_numpy_archive(Path(cfg.init_from)):  # by content: a missing file is named as such
        raise KeypointTrainError(
            f"--init-from {cfg.init_from} is a numpy runtime, which holds no training state: "
            f"pass its torch checkpoint, {Path(cfg.init_from).with_suffix('.pt')}"
        )
    model, payload = load_keypoint_checkpoint(cfg.init_from)
    stored = model.config()
    differ = {
        k: v for k, v in config.items() if stored.get(k) != (list(v) if isinstance(v, tuple) else v)
    }
    if differ:
        raise KeypointTrainError(
            f"--init-from {cfg.init_from} is a model with "
            + ", ".join(f"{k}={stored.get(k)!r}" for k in differ)
            + f", not {', '.join(f'{k}={v!r}' for k, v in differ.items())}: drop those "
            "--model-config values (the checkpoint's architecture is used)"
        )
    model.train()
    return model, payload


def _device(name: str) -> torch.device:
    problem = device_problem(name)
    if problem is not None:
        raise KeypointTrainError(problem)
    return torch.device(name)


def _validate(model: Agnostic2D, batch: RenderedBatch) -> dict[str, float]:
    model.eval()
    out: dict[str, float] = {}
    with torch.no_grad():
        target = quat_to_matrix(batch.targets)
        for causal, tag in ((True, "causal"), (False, "clip")):
            if causal and model.centered:
                continue
            d6, _ = model(batch.features, causal)
            out[f"direction_error_deg_{tag}"] = direction_error_deg(
                rotation_6d_to_matrix(d6), target
            )
    return out


def keypoint_payload(path: str | Path) -> dict[str, Any] | None:
    """The contents of ``path`` if it is a .pt file written by :func:`save_keypoint_checkpoint`,
    else None (a missing, foreign or damaged file: for the other loaders to report)."""
    p = Path(path)
    if not (p.is_file() and p.suffix == ".pt"):
        return None
    try:
        payload = torch.load(p, map_location="cpu", weights_only=True)
    except Exception:  # torch raises many types for foreign files
        return None
    ours = isinstance(payload, dict) and payload.get("format") == CHECKPOINT_FORMAT
    return payload if ours else None


def is_keypoint_checkpoint(path: str | Path) -> bool:
    """Whether ``path`` is a .pt file written by :func:`save_keypoint_checkpoint`."""
    return keypoint_payload(path) is not None


def export_keypoint_checkpoint(
    checkpoints: Path | Sequence[Path], out: Path | None, *, force: bool
) -> Path:
    """``export`` for the keypoint model: the runtime ``.npz`` of one checkpoint (named after
    its file, with its sha256), or of several as one ensemble whose answers are averaged
    (named after ``out``; each model's file, sha256, step, validation and training command in
    ``metadata["ensemble"]``); checked by loading it back."""
    from robot_retarget.errors import MotionFormatError
    from robot_retarget.runtime.agnostic2d import load_agnostic2d

    paths = [checkpoints] if isinstance(checkpoints, Path) else list(checkpoints)
    if not paths:
        raise ValueError("export needs at least one checkpoint")
    target = out or paths[0].with_suffix(".npz")
    if target.suffix != ".npz":
        raise MotionFormatError("the runtime file must end in .npz", path=target)
    if target.exists() and not force:
        raise MotionFormatError("already exists; pass --force to replace it", path=target)
    loaded = [(p, *load_keypoint_checkpoint(p)) for p in paths]
    digests = [hashlib.sha256(p.read_bytes()).hexdigest() for p in paths]
    first, model, payload = loaded[0]
    metadata = dict(payload.get("metadata", {}))
    if len(loaded) > 1:
        metadata["ensemble"] = [
            {
                "checkpoint": p.name,
                "checkpoint_sha256": digest,
                "step": pl.get("metadata", {}).get("step"),
                "validation": pl.get("metadata", {}).get("validation"),
                "command": pl.get("metadata", {}).get("command"),
            }
            for (p, _m, pl), digest in zip(loaded, digests, strict=True)
        ]
    try:  # the runtime refuses centred and causal models mixed
        runtime = Agnostic2DRuntime(
            model.export_weights(),
            name=first.stem if len(loaded) == 1 else target.stem,
            checkpoint_sha256=digests[0],
            data_hash=str(payload.get("data_hash", "")),
            metadata=metadata,
            ensemble=tuple(m.export_weights() for _p, m, _pl in loaded[1:]),
        )
    except ValueError as exc:
        raise ModelLoadError(str(exc), path=first) from None
    tmp = target.with_name(f".{target.name}.tmp")
    save_agnostic2d(runtime, tmp)
    load_agnostic2d(tmp)  # refuse to leave a file that does not load back
    os.replace(tmp, target)
    return target
