"""Training data for the retargeting models: BVH clips → subject split → batches of windows.

Pipeline (NKN / PMnet / TDCN practice):

1. every BVH file under a folder is loaded onto the canonical 22-joint skeleton
   (:func:`robot_retarget.motion.load_motion`) and resampled to a common rate (30 fps);
   the result is cached as one ``.npz`` keyed by a hash of the files' bytes, so later runs
   skip the BVH parsing;
2. clips are split *by subject* (folder name, else the file-name prefix before ``_``): the
   validation subjects are never seen in training;
3. :class:`WindowSampler` draws batches of fixed-length windows (60 frames) and gives each a
   target skeleton: the source's own (probability 0.5, the papers' B = A case), another
   training subject's, or a robot's canonical skeleton, with skeleton augmentation — a random
   global scale (TDCN: [0.5, 1.5]) and random per-bone scales (left/right kept symmetric).

The papers' preprocessing (local pose relative to the root with the heading removed; root
velocity x, y, z and yaw rate) is :func:`robot_retarget.nn.features.compute_features`; the
models apply it to the raw windows this module yields, and :func:`fit_features` gives the
training-set statistics for the models' input normalisation.

Default validation subjects (:data:`DEFAULT_VALIDATION_SUBJECTS`): 06 (basketball dribbling,
turns, shooting: arm-heavy motion, MotionBuilder conversion), 08 (walking and striding, mb2)
and 12 (walking, DAZ conversion). Two mb2 subjects with their own calibrated skeletons and
different motion types plus one DAZ subject, ≈ 20 % of the frames; every motion type of the
validation set (walking, arm work, turning) also occurs in training (02, 05, 07, 10, 13, 14).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import MotionFormatError, RetargetError
from robot_retarget.motion import HumanMotion
from robot_retarget.motion.human_motion import load_bvh_motion
from robot_retarget.motion.native_pose import NativePose, native_pose
from robot_retarget.nn.features import MotionFeatures, compute_features
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.skeleton.armatures import ArmatureTopology, TopologyError
from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    MIRROR_PAIRS,
    Joint,
)
from robot_retarget.skeleton.skeleton import Skeleton

DEFAULT_FPS = 30.0
DEFAULT_WINDOW_FRAMES = 60
DEFAULT_VALIDATION_SUBJECTS: tuple[str, ...] = ("06", "08", "12")
DEFAULT_ROBOTS: tuple[str, ...] = ("op3", "poppy_humanoid")

# Bumped whenever what goes into the cache changes, so stale caches are never read.
_CACHE_VERSION = 3  # 2: motions relative to the canonical T-pose; 3: native poses (SAN)

_NUM_JOINTS = len(CANONICAL_JOINTS)


class DatasetError(RetargetError):
    """The training data cannot be used as asked: names the folder and what to change."""

    def __init__(self, message: str, *, path: str | Path | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path is not None else message)


@dataclass(frozen=True, eq=False)
class Clip:
    """One motion on the canonical skeleton: ``local_quats`` (T, 22, 4), ``root_pos`` (T, 3) m,
    ``offsets`` (22, 3) m (the performer's rest skeleton), at ``fps``; ``native`` the same
    frames on the file's own skeleton (robot_retarget.motion.native_pose), for SAN."""

    name: str
    subject: str
    local_quats: FloatArray = field(repr=False)
    root_pos: FloatArray = field(repr=False)
    offsets: FloatArray = field(repr=False)
    fps: float
    height_m: float
    native: NativePose | None = field(default=None, repr=False)

    @property
    def num_frames(self) -> int:
        return int(self.local_quats.shape[0])

    @property
    def skeleton(self) -> Skeleton:
        return Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, self.offsets)

    def motion(self) -> HumanMotion:
        """The clip as a HumanMotion (for FK, export, evaluation)."""
        return HumanMotion(
            self.skeleton,
            self.local_quats,
            self.root_pos,
            self.fps,
            source_path=self.name,
            height_m=self.height_m,
        )


@dataclass(frozen=True, eq=False)
class MotionDataset:
    """Clips with the hash of the data they came from (see :func:`load_dataset`)."""

    clips: tuple[Clip, ...]
    data_hash: str
    fps: float

    @property
    def subjects(self) -> tuple[str, ...]:
        return tuple(sorted({c.subject for c in self.clips}))

    @property
    def num_frames(self) -> int:
        return sum(c.num_frames for c in self.clips)

    def subset(self, subjects: Iterable[str]) -> MotionDataset:
        """The clips of ``subjects``; the hash names the parent data and the subject set."""
        keep = sorted(set(subjects))
        clips = tuple(c for c in self.clips if c.subject in keep)
        digest = hashlib.sha256(f"{self.data_hash}:{','.join(keep)}".encode()).hexdigest()
        return MotionDataset(clips, digest, self.fps)

    def only(self, subjects: Iterable[str]) -> MotionDataset:
        """The clips of ``subjects`` (scoring needs no training subjects, unlike
        :meth:`split`); raises DatasetError for a subject the data does not hold."""
        keep = set(subjects)
        self._check_known(keep, "validation", "--val-subjects")
        return self.subset(keep)

    def without(self, subjects: Iterable[str]) -> MotionDataset:
        """The clips of every subject but ``subjects`` (a held-out test fold: neither trained
        nor validated on); raises DatasetError for a subject the data does not hold."""
        drop = set(subjects)
        self._check_known(drop, "excluded", "--exclude-subjects")
        return self.subset(s for s in self.subjects if s not in drop)

    def _check_known(self, subjects: set[str], role: str, option: str) -> None:
        """DatasetError naming the ``subjects`` the data does not hold, if any."""
        unknown = sorted(subjects - set(self.subjects))
        if unknown:
            raise DatasetError(
                f"{role} subject(s) {unknown} are not in the data; subjects are "
                f"{list(self.subjects)} (pass {option} with some of them)"
            )

    def split(
        self, validation_subjects: Sequence[str] = DEFAULT_VALIDATION_SUBJECTS
    ) -> tuple[MotionDataset, MotionDataset]:
        """(training, validation) by subject; raises DatasetError if either would be empty."""
        val = set(validation_subjects)
        self._check_known(val, "validation", "--val-subjects")
        train = [s for s in self.subjects if s not in val]
        if not train:
            raise DatasetError(
                f"every subject {list(self.subjects)} is a validation subject; leave at least "
                "one for training"
            )
        return self.subset(train), self.subset(val)

    def distinct_skeletons(self) -> list[FloatArray]:
        """Rest offsets (22, 3) of each distinct skeleton (DAZ subjects share one)."""
        out: list[FloatArray] = []
        for c in self.clips:
            if not any(np.allclose(c.offsets, o, atol=1e-9) for o in out):
                out.append(c.offsets)
        return out


def subject_of(path: Path, root: Path) -> str:
    """Subject of a clip: its first folder below ``root``, else the file-name prefix before
    ``_`` (CMU names clips ``SS_CC.bvh``)."""
    rel = path.relative_to(root)
    if len(rel.parts) > 1:
        return rel.parts[0]
    return path.stem.split("_")[0]


def find_clips(data_dir: str | Path) -> list[Path]:
    """Every ``.bvh`` file under ``data_dir`` (any depth, any case), sorted."""
    root = Path(data_dir)
    if root.is_file():
        raise DatasetError(
            "a file, not a folder: --data names the folder that holds the BVH clips (one "
            "subfolder per performer, or files named SUBJECT_CLIP.bvh)",
            path=root,
        )
    if not root.is_dir():
        raise DatasetError("no such data folder; pass --data with a folder of BVH clips", path=root)
    paths = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix.lower() == ".bvh")
    if not paths:
        raise DatasetError("no .bvh files found in the data folder", path=root)
    return paths


def files_hash(paths: Sequence[Path], root: Path) -> str:
    """SHA-256 (hex) over the files' relative names and bytes: the data hash."""
    h = hashlib.sha256()
    for p in paths:
        h.update(p.relative_to(root).as_posix().encode())
        h.update(b"\0")
        with p.open("rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def default_cache_dir() -> Path:
    """$ROBOT_RETARGET_CACHE, else $XDG_CACHE_HOME/robot-retarget, else ~/.cache/robot-retarget."""
    env = os.environ.get("ROBOT_RETARGET_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "robot-retarget"


def load_dataset(
    data_dir: str | Path,
    *,
    fps: float = DEFAULT_FPS,
    max_frames: int | None = None,
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
) -> MotionDataset:
    """Every BVH clip under ``data_dir`` on the canonical skeleton, resampled to ``fps``.

    ``max_frames`` keeps only each clip's first frames (at the file's own rate; for quick
    runs). Results are cached in ``cache_dir`` (default :func:`default_cache_dir`) as
    ``dataset-<hash>.npz``; the key covers the files' bytes, ``fps``, ``max_frames``, the
    cache format and the motion loader's source code, so neither a changed file nor a changed
    loader is ever served stale.
    """
    root = Path(data_dir)
    paths = find_clips(root)
    digest = files_hash(paths, root)
    key = hashlib.sha256(
        f"{digest}:{float(fps)!r}:{max_frames}:v{_CACHE_VERSION}:{_loader_fingerprint()}".encode()
    ).hexdigest()
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    cache_file = cache / f"dataset-{key[:24]}.npz"
    if use_cache and cache_file.is_file():
        try:
            return _read_cache(cache_file, digest, float(fps))
        except (OSError, KeyError, ValueError, TopologyError):
            pass  # unreadable or foreign cache: rebuild it below
    clips = tuple(_load_clip(p, root, fps, max_frames) for p in paths)
    dataset = MotionDataset(clips, digest, float(fps))
    if use_cache:
        _write_cache(cache_file, dataset)
    return dataset


def _loader_fingerprint() -> str:
    """Hash of the motion loader's source (motion and skeleton packages): a changed BVH
    mapping or rest-pose convention never serves a stale cache."""
    import robot_retarget.motion as motion_pkg
    import robot_retarget.skeleton as skeleton_pkg

    h = hashlib.sha256()
    for pkg in (motion_pkg, skeleton_pkg):
        for path in sorted(Path(str(pkg.__file__)).parent.glob("*.py")):
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _load_clip(path: Path, root: Path, fps: float, max_frames: int | None) -> Clip:
    try:
        bvh, motion = load_bvh_motion(path, max_frames=max_frames)
    except MotionFormatError as exc:
        raise DatasetError(f"cannot load a clip of the data set: {exc}", path=path) from exc
    native: NativePose | None
    try:
        native = native_pose(bvh, motion)
    except TopologyError:
        native = None  # no skeleton-aware view of this file; every other model still uses it
    if abs(motion.fps - fps) > 1e-3 * fps:
        native = None if native is None else native.resample(motion.fps, fps)
        motion = motion.resample(fps)
    return Clip(
        name=path.relative_to(root).as_posix(),
        subject=subject_of(path, root),
        local_quats=np.asarray(motion.local_quats, dtype=np.float64),
        root_pos=np.asarray(motion.root_pos, dtype=np.float64),
        offsets=np.asarray(motion.skeleton.offsets, dtype=np.float64),
        fps=float(motion.fps),
        height_m=float(motion.height_m),
        native=native,
    )


def _write_cache(path: Path, dataset: MotionDataset) -> None:
    lengths = np.array([c.num_frames for c in dataset.clips], dtype=np.int64)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp.npz")
    arrays: dict[str, Any] = dict(
        names=np.array([c.name for c in dataset.clips]),
        subjects=np.array([c.subject for c in dataset.clips]),
        lengths=lengths,
        local_quats=np.concatenate([c.local_quats for c in dataset.clips]),
        root_pos=np.concatenate([c.root_pos for c in dataset.clips]),
        offsets=np.stack([c.offsets for c in dataset.clips]),
        heights=np.array([c.height_m for c in dataset.clips]),
        fps=np.array([c.fps for c in dataset.clips]),
        data_hash=np.array(dataset.data_hash),
        **_native_arrays(dataset.clips),
    )
    np.savez(tmp, **arrays)
    os.replace(tmp, path)  # atomic: a concurrent reader never sees half a file


def _read_cache(path: Path, digest: str, fps: float) -> MotionDataset:
    with np.load(path, allow_pickle=False) as z:
        if str(z["data_hash"]) != digest:
            raise ValueError("cache belongs to other data")
        bounds = np.concatenate([[0], np.cumsum(z["lengths"])])
        quats, root = z["local_quats"], z["root_pos"]
        clips = tuple(
            Clip(
                name=str(z["names"][i]),
                subject=str(z["subjects"][i]),
                local_quats=quats[bounds[i] : bounds[i + 1]],
                root_pos=root[bounds[i] : bounds[i + 1]],
                offsets=z["offsets"][i],
                fps=float(z["fps"][i]),
                height_m=float(z["heights"][i]),
                native=_read_native(z, i),
            )
            for i in range(len(z["lengths"]))
        )
    return MotionDataset(clips, digest, fps)


def _native_arrays(clips: Sequence[Clip]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for i, c in enumerate(clips):
        if c.native is not None:
            out[f"native_topology_{i}"] = np.array(json.dumps(c.native.topology.spec()))
            out[f"native_quats_{i}"] = c.native.local_quats
            out[f"native_offsets_{i}"] = c.native.offsets
    return out


def _read_native(z: Mapping[str, np.ndarray], i: int) -> NativePose | None:
    key = f"native_topology_{i}"
    if key not in z:
        return None
    topology = ArmatureTopology.from_spec(json.loads(str(z[key])))
    return NativePose(topology, z[f"native_quats_{i}"], z[f"native_offsets_{i}"])


def robot_skeletons(names: Sequence[str] = DEFAULT_ROBOTS) -> dict[str, FloatArray]:
    """Canonical-skeleton rest offsets (22, 3) of robots from configs/robots, by name."""
    from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
    from robot_retarget.robot.loader import load_robot_config

    return {
        name: np.array(robot_canonical_skeleton(load_robot_config(name)).offsets) for name in names
    }


# --- skeleton augmentation ---------------------------------------------------------------

# Each joint's offset gets its own random scale; a right joint reuses its left partner's.
_MIRROR: dict[int, int] = {int(Joint[right]): int(Joint[left]) for left, right in MIRROR_PAIRS}
_LEG_CHAIN = (int(Joint.LeftUpLeg), int(Joint.LeftLeg), int(Joint.LeftFoot))


@dataclass(frozen=True)
class Augmentation:
    """Skeleton augmentation and target choice of :class:`WindowSampler`.

    ``global_scale`` (TDCN: [0.5, 1.5]) multiplies every offset; ``bone_scale`` multiplies each
    bone (left/right symmetric); ``p_same`` is the chance a sample's target is its source
    skeleton (the papers' B = A); ``p_robot`` the chance another target is a robot's canonical
    skeleton (robots are never scaled); ``p_augment_source`` the chance the source skeleton is
    augmented too (its root trajectory scaled with its leg length).
    """

    global_scale: tuple[float, float] = (0.5, 1.5)
    bone_scale: tuple[float, float] = (0.8, 1.2)
    p_same: float = 0.5
    p_robot: float = 0.3
    p_augment_source: float = 0.5


def augment_offsets(
    offsets: FloatArray, rng: np.random.Generator, augmentation: Augmentation
) -> FloatArray:
    """Offsets (22, 3) with random per-bone (symmetric) and global scales applied."""
    lo, hi = augmentation.bone_scale
    factors = rng.uniform(lo, hi, size=_NUM_JOINTS)
    for right, left in _MIRROR.items():
        factors[right] = factors[left]
    g_lo, g_hi = augmentation.global_scale
    return np.asarray(offsets * factors[:, None] * rng.uniform(g_lo, g_hi), dtype=np.float64)


def leg_length(offsets: FloatArray) -> float:
    """Thigh + shin + hip-to-thigh drop (m): how far the hips are off the ground."""
    return float(sum(np.linalg.norm(offsets[j]) for j in _LEG_CHAIN))


@dataclass(frozen=True)
class _Window:
    quats: FloatArray
    root: FloatArray
    offsets: FloatArray
    native_quats: FloatArray | None = None
    native_offsets: FloatArray | None = None


class WindowSampler:
    """Random batches of windows with target skeletons (see the module docstring).

    Batch ``step`` is a pure function of (``seed``, ``step``): resuming a run at step n draws
    the same batches as the uninterrupted run.
    """

    def __init__(
        self,
        dataset: MotionDataset,
        *,
        window_frames: int = DEFAULT_WINDOW_FRAMES,
        batch_size: int = 32,
        robot_offsets: Mapping[str, FloatArray] | None = None,
        augmentation: Augmentation | None = None,
        real_motion: bool = False,
        native: bool = False,
        canonical_share: float = 0.5,
        seed: int = 0,
    ) -> None:
        self.clips = [c for c in dataset.clips if c.num_frames >= window_frames]
        if not self.clips:
            raise DatasetError(
                f"no clip has {window_frames} frames at {dataset.fps:g} fps; use shorter "
                "windows (--window) or longer clips"
            )
        self.window_frames = window_frames
        self.batch_size = batch_size
        self.augmentation = augmentation or Augmentation()
        self.real_motion = real_motion
        self.seed = seed
        self.human_skeletons = dataset.distinct_skeletons()
        self.robot_skeletons = list((robot_offsets or {}).values())
        starts = np.array([c.num_frames - window_frames + 1 for c in self.clips], dtype=np.float64)
        self._clip_p = starts / starts.sum()  # every window equally likely
        self.native = native
        self.canonical_share = canonical_share
        self._native_groups: list[tuple[str, np.ndarray]] = []
        if native:
            groups: dict[str, list[int]] = {}
            for i, c in enumerate(self.clips):
                if c.native is not None:
                    groups.setdefault(c.native.topology.name, []).append(i)
            if not groups:
                raise DatasetError(
                    "no clip has a view on its own skeleton (native pose), which SAN's "
                    "encoders read; its BVH files' end-effectors could not be named"
                )
            self._native_groups = [(k, np.array(v)) for k, v in sorted(groups.items())]
            weight = np.array([starts[idx].sum() for _, idx in self._native_groups])
            self._group_p = weight / weight.sum()

    def _window(self, rng: np.random.Generator) -> tuple[Clip, int]:
        clip = self.clips[int(rng.choice(len(self.clips), p=self._clip_p))]
        return clip, int(rng.integers(0, clip.num_frames - self.window_frames + 1))

    def _source(self, rng: np.random.Generator) -> _Window:
        clip, start = self._window(rng)
        sl = slice(start, start + self.window_frames)
        offsets, root = clip.offsets, clip.root_pos[sl]
        if rng.random() < self.augmentation.p_augment_source:
            offsets = augment_offsets(clip.offsets, rng, self.augmentation)
            root = root * (leg_length(offsets) / leg_length(clip.offsets))
        return _Window(clip.local_quats[sl], root, offsets)

    def _target(self, rng: np.random.Generator, source: FloatArray) -> tuple[FloatArray, bool]:
        if rng.random() < self.augmentation.p_same:
            return source, True
        if self.robot_skeletons and rng.random() < self.augmentation.p_robot:
            return self.robot_skeletons[int(rng.integers(len(self.robot_skeletons)))], False
        human = self.human_skeletons[int(rng.integers(len(self.human_skeletons)))]
        return augment_offsets(human, rng, self.augmentation), False

    def _real(self, rng: np.random.Generator, target: FloatArray) -> _Window:
        """Another window's rotations performed by the target skeleton (NKN's real motion)."""
        clip, start = self._window(rng)
        sl = slice(start, start + self.window_frames)
        scale = leg_length(target) / leg_length(clip.offsets)
        return _Window(clip.local_quats[sl], clip.root_pos[sl] * scale, target)

    def _native_source(self, rng: np.random.Generator, pool: np.ndarray) -> _Window:
        """A window of one of the clips ``pool``, with its native pose; the source is only
        scaled as a whole (its joints' own bones are not the canonical ones)."""
        p = self._clip_p[pool] / self._clip_p[pool].sum()
        clip = self.clips[int(pool[int(rng.choice(len(pool), p=p))])]
        start = int(rng.integers(0, clip.num_frames - self.window_frames + 1))
        sl = slice(start, start + self.window_frames)
        native = clip.native
        assert native is not None  # the pool holds clips with a native pose only
        scale = 1.0
        if rng.random() < self.augmentation.p_augment_source:
            scale = float(rng.uniform(*self.augmentation.global_scale))
        return _Window(
            clip.local_quats[sl],
            clip.root_pos[sl] * scale,
            clip.offsets * scale,
            native.local_quats[sl],
            native.offsets * scale,
        )

    def sample(self, step: int, stream: int = 0) -> RetargetBatch:
        """Batch number ``step`` ≥ 0 of random stream ``stream`` (float32 tensors, CPU).
        With ``native``, a share ``canonical_share`` of the batches are canonical (the live
        path's input, read by the canonical encoder); in the others every clip shares one
        native skeleton, drawn in proportion to its windows, and the batch carries their native
        poses."""
        rng = np.random.default_rng([self.seed, stream, step])
        domain: str | None = None
        if self.native and rng.random() >= self.canonical_share:
            g = int(rng.choice(len(self._native_groups), p=self._group_p))
            domain, pool = self._native_groups[g]
            sources = [self._native_source(rng, pool) for _ in range(self.batch_size)]
        else:
            sources = [self._source(rng) for _ in range(self.batch_size)]
        targets = [self._target(rng, s.offsets) for s in sources]
        reals = [self._real(rng, t) for t, _ in targets] if self.real_motion else None

        def t32(arrays: Sequence[FloatArray]) -> torch.Tensor:
            return torch.from_numpy(np.stack(arrays).astype(np.float32))

        return RetargetBatch(
            src_local_quats=t32([s.quats for s in sources]),
            src_root_pos=t32([s.root for s in sources]),
            src_offsets=t32([s.offsets for s in sources]),
            tgt_offsets=t32([t for t, _ in targets]),
            same_skeleton=torch.tensor([same for _, same in targets], dtype=torch.bool),
            real_local_quats=None if reals is None else t32([r.quats for r in reals]),
            real_root_pos=None if reals is None else t32([r.root for r in reals]),
            native_domain=domain,
            native_quats=None if domain is None else t32([_native(s)[0] for s in sources]),
            native_offsets=None if domain is None else t32([_native(s)[1] for s in sources]),
        )


def _native(window: _Window) -> tuple[FloatArray, FloatArray]:
    if window.native_quats is None or window.native_offsets is None:
        raise ValueError("this window was drawn without its native pose")
    return window.native_quats, window.native_offsets


def fit_features(sampler: WindowSampler, batches: int = 8) -> tuple[MotionFeatures, torch.Tensor]:
    """Features and their offsets (N, 22, 3) of a few batches, for the models'
    ``fit_normalization``: each source window on its own skeleton and on its target skeleton
    (root scaled by leg length), so both the source and the target skeleton distributions
    (robots included) are covered. Drawn from stream 1: never a training batch."""
    feats: list[MotionFeatures] = []
    offsets: list[torch.Tensor] = []
    for i in range(batches):
        b = sampler.sample(i, stream=1)
        legs_src = torch.tensor([leg_length(o) for o in b.src_offsets.double().numpy()])
        legs_tgt = torch.tensor([leg_length(o) for o in b.tgt_offsets.double().numpy()])
        tgt_root = b.src_root_pos * (legs_tgt / legs_src).to(b.src_root_pos)[:, None, None]
        for root, offs in ((b.src_root_pos, b.src_offsets), (tgt_root, b.tgt_offsets)):
            feats.append(compute_features(b.src_local_quats, root, offs))
            offsets.append(offs)
    merged = MotionFeatures(
        local_pos=torch.cat([f.local_pos for f in feats]),
        root_vel=torch.cat([f.root_vel for f in feats]),
        local_quats=torch.cat([f.local_quats for f in feats]),
        yaw=torch.cat([f.yaw for f in feats]),
    )
    return merged, torch.cat(offsets)
