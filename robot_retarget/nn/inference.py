"""Run a retargeting model: load it by name or path, retarget whole clips or live frames.

Names resolve, in order, to the built-in baselines (``copy``, ``copy-scaled``) and to the
checkpoints shipped in ``robot_retarget/data/checkpoints/<name>.pt``; anything else that
names an existing file is loaded as a checkpoint path. :data:`DEFAULT_MODEL` is what the
rest of the product uses when no ``--model`` is given.

Two paths, same numbers for causal models:

- :func:`retarget_clip` / :func:`retarget_motion`: a whole clip in one pass (offline);
- :class:`OnlineRetargeter`: ``step()`` once per incoming frame (live), numpy in and out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ModelLoadError
from robot_retarget.motion import HumanMotion
from robot_retarget.motion.native_pose import NativePose
from robot_retarget.nn.checkpoint import load_checkpoint
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.registry import build_model
from robot_retarget.nn.models.san import SAN
from robot_retarget.npz_errors import is_numpy_archive
from robot_retarget.runtime.loader import KEYPOINT_MODEL_PREFIX
from robot_retarget.runtime.model import not_a_model
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS
from robot_retarget.skeleton.skeleton import Skeleton

CHECKPOINT_DIR = Path(__file__).resolve().parents[1] / "data" / "checkpoints"
BUILTIN_MODELS: tuple[str, ...] = ("copy", "copy-scaled")
DEFAULT_MODEL = "default"
"""Name of the shipped checkpoint the product uses by default (data/checkpoints/default.pt)."""

_J = len(CANONICAL_JOINTS)


@dataclass(frozen=True)
class LoadedModel:
    """A model ready for inference (eval mode) and where it came from.

    ``path`` is None for the built-in baselines; ``skeletons``, ``data_hash`` and ``metadata``
    are what the checkpoint stored (empty for baselines).
    """

    name: str
    model: RetargetModel
    path: Path | None = None
    skeletons: dict[str, FloatArray] = field(default_factory=dict)
    data_hash: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def architecture(self) -> str:
        """Registry name of the network (``pmnet``, ``nkn``, ``copy``, …)."""
        return self.model.name


def shipped_checkpoints(directory: Path | None = None) -> dict[str, Path]:
    """Checkpoints shipped with the package (default :data:`CHECKPOINT_DIR`), by file stem."""
    directory = CHECKPOINT_DIR if directory is None else directory
    if not directory.is_dir():
        return {}
    return {p.stem: p for p in sorted(directory.glob("*.pt"))}


def available_models() -> tuple[str, ...]:
    """Every name :func:`load_model` accepts (paths aside); the shipped 2D keypoint models
    (``agnostic2d*``) lift keypoints for ``--keypoint-model`` and are no retargeting model."""
    return BUILTIN_MODELS + tuple(
        n
        for n in shipped_checkpoints()
        if n not in BUILTIN_MODELS and not n.startswith(KEYPOINT_MODEL_PREFIX)
    )


def checkpoint_file(text: str) -> Path | None:
    """The checkpoint a path names: the file, or a training run folder's ``best.pt``; None
    when ``text`` names no file or folder (it may be a model's name). A runtime ``.npz``, a
    folder without ``best.pt`` and a ``.pt`` or folder path that does not exist are a
    ModelLoadError saying so."""
    candidate = Path(text).expanduser()
    if candidate.is_dir():
        if (candidate / "best.pt").is_file():
            return candidate / "best.pt"  # a training run's folder
        raise ModelLoadError(
            f"{text}: a folder without best.pt (a training run folder holds one after its "
            "first validation); name a .pt checkpoint",
            model=text,
        )
    kind = not_a_model(candidate)
    if kind is not None:
        raise ModelLoadError(
            f"{text}: {kind}, not a model: name a model such as default, a .pt checkpoint or a "
            "training run folder",
            model=text,
        )
    if candidate.is_file() and is_numpy_archive(candidate):  # by content: names can be wrong
        raise ModelLoadError(
            f"{text}: a numpy runtime file, already exported (convert, stream and the API take "
            "it as --model); this command reads the .pt checkpoint it was exported from",
            model=text,
        )
    if candidate.is_file():
        return candidate
    if candidate.suffix in (".pt", ".npz") or len(candidate.parts) > 1:
        raise ModelLoadError(f"{text}: no such checkpoint file", model=text)
    return None


def load_model(
    name_or_path: str | Path = DEFAULT_MODEL, *, device: str = "cpu", runtime_files: bool = False
) -> LoadedModel:
    """A model by built-in name, shipped checkpoint name or checkpoint path.

    Raises ModelLoadError naming the available models when nothing matches; ``runtime_files``:
    the caller also takes a runtime ``.npz`` (load_runtime_model), so that error offers one.
    """
    text = str(name_or_path)
    if text in BUILTIN_MODELS:
        model = build_model(text).eval()
        return LoadedModel(name=text, model=model.to(device))
    shipped = shipped_checkpoints()
    path = shipped.get(text) or checkpoint_file(text)
    if path is None:
        raise ModelLoadError(
            f"no model {text!r}: not a built-in model, a shipped checkpoint or a checkpoint "
            f"file; available names: {', '.join(available_models())} (or pass "
            f"{'a runtime .npz written by export, ' if runtime_files else ''}a .pt path or a "
            "training run folder)",
            model=text,
        )
    loaded = load_checkpoint(path)
    name = text if text in shipped else str(path)
    return LoadedModel(
        name=name,
        model=loaded.model.to(device).eval(),
        path=path,
        skeletons=loaded.skeletons,
        data_hash=loaded.data_hash,
        metadata=loaded.metadata,
    )


def native_domain(net: RetargetModel, native: NativePose, frames: int) -> str:
    """The domain of ``net`` (a SAN) that reads ``native``'s skeleton; ValueError otherwise."""
    if not isinstance(net, SAN):
        raise ValueError(
            f"model {net.name!r} reads canonical joints only; a clip on its own skeleton is "
            "read by skeleton-aware models (san)"
        )
    domain = net.domain_of(native.topology)
    if domain is None:
        raise ValueError(
            f"this SAN has no encoder for skeleton {native.topology.name!r}; it was trained on "
            f"{list(net.domain_names)} (train one on data with that skeleton)"
        )
    if native.num_frames != frames:
        raise ValueError(f"native pose has {native.num_frames} frames, the clip {frames}")
    return domain


def _model_of(model: LoadedModel | RetargetModel) -> RetargetModel:
    return model.model if isinstance(model, LoadedModel) else model


def _device_of(model: RetargetModel) -> torch.device:
    param = next(model.parameters(), None)
    return torch.device("cpu") if param is None else param.device


def _check(name: str, a: FloatArray, shape: tuple[int, ...]) -> None:
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")


def retarget_clip(
    model: LoadedModel | RetargetModel,
    local_quats: npt.ArrayLike,
    root_pos: npt.ArrayLike,
    source_offsets: npt.ArrayLike,
    target_offsets: npt.ArrayLike,
    *,
    native: NativePose | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Retarget one whole clip: (T, 22, 4), (T, 3), (22, 3), (22, 3) → target rotations
    (T, 22, 4) unit and root positions (T, 3) metres (float64 numpy).

    ``native``: the same frames on the file's own skeleton, read by a skeleton-aware model
    (SAN) through that skeleton's own encoder; other models refuse it."""
    net = _model_of(model)
    q = np.asarray(local_quats, dtype=np.float64)
    root = np.asarray(root_pos, dtype=np.float64)
    t = q.shape[0]
    _check("local_quats", q, (t, _J, 4))
    _check("root_pos", root, (t, 3))
    src = np.asarray(source_offsets, dtype=np.float64)
    tgt = np.asarray(target_offsets, dtype=np.float64)
    _check("source_offsets", src, (_J, 3))
    _check("target_offsets", tgt, (_J, 3))
    dev = _device_of(net)

    def tensor(a: FloatArray) -> torch.Tensor:
        return torch.tensor(a[None], device=dev)

    net.eval()
    with torch.inference_mode():
        if native is not None:
            domain = native_domain(net, native, t)
            assert isinstance(net, SAN)  # native_domain refuses every other model
            out = net.forward_native(
                domain,
                tensor(q),
                tensor(root),
                tensor(src),
                tensor(native.local_quats),
                tensor(native.offsets),
                tensor(tgt),
            )
        else:
            out = net(tensor(q), tensor(root), tensor(src), tensor(tgt))
        quats = out.local_quats[0].double().cpu().numpy()
        pos = out.root_pos[0].double().cpu().numpy()
    return quats / np.linalg.norm(quats, axis=-1, keepdims=True), pos


def retarget_motion(
    model: LoadedModel | RetargetModel, motion: HumanMotion, target: Skeleton
) -> HumanMotion:
    """``motion`` retargeted onto ``target`` (a canonical skeleton, e.g. a robot's)."""
    quats, root = retarget_clip(
        model, motion.local_quats, motion.root_pos, motion.skeleton.offsets, target.offsets
    )
    return HumanMotion(target, quats, root, motion.fps, source_path=motion.source_path)


class OnlineRetargeter:
    """Frame-by-frame retargeting for live sources (numpy in and out).

    ``step`` uses only this and earlier frames; call :meth:`reset` before a new sequence.
    Runs the model in eval mode under ``torch.inference_mode``.
    """

    def __init__(
        self,
        model: LoadedModel | RetargetModel,
        source_offsets: npt.ArrayLike,
        target_offsets: npt.ArrayLike,
    ) -> None:
        self.model = _model_of(model).eval()
        param = next(self.model.parameters(), None)
        self._dtype = torch.float64 if param is None else param.dtype
        self._device = _device_of(self.model)
        src = np.asarray(source_offsets, dtype=np.float64)
        tgt = np.asarray(target_offsets, dtype=np.float64)
        _check("source_offsets", src, (_J, 3))
        _check("target_offsets", tgt, (_J, 3))
        self._src = self._tensor(src)
        self._tgt = self._tensor(tgt)
        self.reset()

    def _tensor(self, a: FloatArray) -> torch.Tensor:
        # A copy: inputs may be read-only views (HumanMotion's arrays), which torch warns about.
        return torch.tensor(a[None], dtype=self._dtype, device=self._device)

    def reset(self) -> None:
        """Start a new sequence: the next :meth:`step` is frame 0."""
        self.model.reset()

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """One frame: (22, 4), (3,) → target rotations (22, 4) and root position (3,)."""
        q = np.asarray(local_quats, dtype=np.float64)
        root = np.asarray(root_pos, dtype=np.float64)
        _check("local_quats", q, (_J, 4))
        _check("root_pos", root, (3,))
        with torch.inference_mode():
            out = self.model.step(self._tensor(q), self._tensor(root), self._src, self._tgt)
            quats = out.local_quats[0].to("cpu", torch.float64).numpy()
            pos = out.root_pos[0].to("cpu", torch.float64).numpy()
        return quats, pos
