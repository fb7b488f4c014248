"""A retargeting network as the live path runs it: numpy only, no torch.

A :class:`RuntimeModel` is what a trained model exports for streaming and converting: its
architecture, its weights as numpy arrays, and where it came from. ``online(source, target)``
builds the per-frame step for one performer and one robot skeleton, the same arithmetic as the
torch model's online step (tested to float32 rounding). Torch is needed to train a model, not
to run one.

File format (``.npz``, written by ``python launch.py export`` and ``train``): one array per
weight under a readable dotted name (``correction_layers.0.weight``) and ``__meta__``, a JSON
document: ``format`` (this module's :data:`FORMAT_VERSION`), ``architecture``, ``name``,
``checkpoint_sha256`` (the torch checkpoint it was exported from), ``data_hash`` and
``metadata`` (what the checkpoint stored). Loading checks every name and shape the
architecture needs and says which one is wrong.
"""

from __future__ import annotations

import dataclasses
import os
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ModelLoadError
from robot_retarget.runtime.copy import FastCopyRetargeter, rest_height_m
from robot_retarget.runtime.frame import check_offsets
from robot_retarget.runtime.npz_file import read_runtime_npz, write_runtime_npz
from robot_retarget.runtime.pmnet import FastPMnetRetargeter, PMnetWeights
from robot_retarget.runtime.residual import FastResidualRetargeter
from robot_retarget.runtime.residual_weights import ResidualWeights
from robot_retarget.runtime.san import FastSANRetargeter, SANWeights
from robot_retarget.runtime.tdcn import FastTDCNRetargeter, TDCNWeights
from robot_retarget.skeleton.foot_lock_spec import CONTACT_FPS

FORMAT_VERSION = 1
Weights = ResidualWeights | PMnetWeights | TDCNWeights | SANWeights


class OnlineStep(Protocol):
    """What the live step needs from a network: per-frame ``step`` and ``reset``."""

    def reset(self) -> None: ...

    def step(
        self, local_quats: npt.ArrayLike, root_pos: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]: ...


def _copy(_w: Weights | None, src: FloatArray, tgt: FloatArray, _rate: float) -> OnlineStep:
    return FastCopyRetargeter(src, tgt, 1.0)


def _copy_scaled(_w: Weights | None, src: FloatArray, tgt: FloatArray, _rate: float) -> OnlineStep:
    return FastCopyRetargeter(src, tgt, rest_height_m(tgt) / rest_height_m(src))


def _residual(w: Weights | None, src: FloatArray, tgt: FloatArray, rate: float) -> OnlineStep:
    assert isinstance(w, ResidualWeights)  # guaranteed by RuntimeModel.__post_init__
    return FastResidualRetargeter(w, src, tgt, frame_rate_hz=rate)


def _pmnet(w: Weights | None, src: FloatArray, tgt: FloatArray, _rate: float) -> OnlineStep:
    assert isinstance(w, PMnetWeights)
    return FastPMnetRetargeter(w, src, tgt)


def _tdcn(w: Weights | None, src: FloatArray, tgt: FloatArray, _rate: float) -> OnlineStep:
    assert isinstance(w, TDCNWeights)
    return FastTDCNRetargeter(w, src, tgt)


def _san(w: Weights | None, src: FloatArray, tgt: FloatArray, _rate: float) -> OnlineStep:
    assert isinstance(w, SANWeights)
    return FastSANRetargeter(w, src, tgt)


# architecture → (weights class or None, step factory (weights, source, target, frame rate))
StepFactory = Callable[[Weights | None, FloatArray, FloatArray, float], OnlineStep]
ARCHITECTURES: dict[str, tuple[type[Weights] | None, StepFactory]] = {
    "copy": (None, _copy),
    "copy-scaled": (None, _copy_scaled),
    "residual": (ResidualWeights, _residual),
    "pmnet": (PMnetWeights, _pmnet),
    "tdcn": (TDCNWeights, _tdcn),
    "san": (SANWeights, _san),
}


@dataclass(frozen=True)
class RuntimeModel:
    """A network ready for the live path: ``architecture`` (a key of :data:`ARCHITECTURES`),
    ``weights`` (None for the parameter-free baselines), provenance."""

    name: str
    architecture: str
    weights: Weights | None = None
    path: Path | None = None
    checkpoint_sha256: str = ""
    data_hash: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.architecture not in ARCHITECTURES:
            raise ModelLoadError(
                f"no numpy runtime for architecture {self.architecture!r} (runtimes: "
                f"{', '.join(ARCHITECTURES)})",
                path=self.path,
            )
        kind = ARCHITECTURES[self.architecture][0]
        if (kind is None) != (self.weights is None) or (
            kind is not None and not isinstance(self.weights, kind)
        ):
            raise ModelLoadError(
                f"{self.architecture} needs {kind.__name__ if kind else 'no'} weights, got "
                f"{type(self.weights).__name__}",
                path=self.path,
            )

    def online(
        self,
        source_offsets: npt.ArrayLike,
        target_offsets: npt.ArrayLike,
        *,
        frame_rate_hz: float = CONTACT_FPS,
        foot_lock: bool | None = None,
    ) -> OnlineStep:
        """The per-frame step for a performer (source) and robot (target) rest skeleton, run at
        ``frame_rate_hz`` (what a step that judges speeds, the residual model's foot lock,
        needs; default: the 30 fps the models are trained at).

        ``foot_lock``: None runs the model as exported (its foot lock if it has one, as the
        torch model and ``eval`` do); False leaves the lock out; True requires one."""
        src = check_offsets("source_offsets", source_offsets)
        tgt = check_offsets("target_offsets", target_offsets)
        weights = self.weights
        if foot_lock is not None and foot_lock != self.has_foot_lock:
            if foot_lock:
                raise no_foot_lock_error(self.name, self.path)
            assert isinstance(weights, ResidualWeights)  # has_foot_lock says so
            weights = dataclasses.replace(weights, foot_lock=False)
        return ARCHITECTURES[self.architecture][1](weights, src, tgt, frame_rate_hz)

    @property
    def has_foot_lock(self) -> bool:
        """Whether the model holds planted feet on its output skeleton (residual models trained
        with ``foot_lock``, :mod:`robot_retarget.nn.models.foot_lock`)."""
        return isinstance(self.weights, ResidualWeights) and self.weights.foot_lock


MODEL_FORMS = (
    "a model name such as default, a runtime .npz written by export, a .pt checkpoint or a "
    "training run folder"
)
"""What ``--model`` takes where a numpy runtime will do (convert, stream, demo, the API)."""

# Files people pass as a model by mistake, by suffix: a clip, or a trajectory convert wrote.
_NOT_MODEL_SUFFIXES = {
    ".bvh": "a BVH motion clip",
    ".csv": "a CSV file (a trajectory or keypoints)",
    ".json": "a JSON file (a trajectory or keypoints)",
}
# The arrays of a trajectory .npz (robot_retarget.motion.trajectory); a runtime has __meta__.
_TRAJECTORY_KEYS = frozenset({"joint_names", "q", "fps"})


def not_a_model(path: Path) -> str | None:
    """What ``path`` is when it is an existing file that holds no model (a motion clip, a robot
    trajectory), for the error; None otherwise (it may still fail to load as a model)."""
    if not path.is_file():
        return None
    suffix = path.suffix.lower()
    if suffix in _NOT_MODEL_SUFFIXES:
        return _NOT_MODEL_SUFFIXES[suffix]
    if suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                keys = set(z.files)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile):
            return None  # the runtime reader says what is wrong with it
        if keys >= _TRAJECTORY_KEYS:
            return "a robot trajectory (joint angles over time, as convert writes)"
    return None


def no_foot_lock_error(name: str, path: Path | None = None) -> ModelLoadError:
    """What asking a model without a foot lock for one raises."""
    return ModelLoadError(
        f"model {name!r} has no foot lock (only residual models trained with one have it): "
        "leave out --foot-lock",
        path=path,
        model=name,
    )


# ----------------------------------------------------------------------------- file format
def _flatten(prefix: str, value: Any, out: dict[str, np.ndarray]) -> None:
    if isinstance(value, tuple):
        for k, item in enumerate(value):
            _flatten(f"{prefix}.{k}", item, out)
    else:
        a = np.asarray(value)
        # Trained weights are float32 in torch: stored as such when that loses nothing.
        if a.dtype == np.float64 and np.array_equal(a.astype(np.float32), a):
            a = a.astype(np.float32)
        out[prefix] = a


def save_runtime(model: RuntimeModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as an ``.npz`` runtime file (see the module docstring)."""
    out = Path(path)
    arrays: dict[str, np.ndarray] = {}
    if model.weights is not None:
        for f in dataclasses.fields(model.weights):
            _flatten(f.name, getattr(model.weights, f.name), arrays)
    meta = {
        "format": FORMAT_VERSION,
        "architecture": model.architecture,
        "name": model.name,
        "checkpoint_sha256": model.checkpoint_sha256,
        "data_hash": model.data_hash,
        "metadata": model.metadata,
    }
    return write_runtime_npz(out, arrays, meta)


def _read_weights(kind: type[Weights], arrays: dict[str, np.ndarray], path: Path) -> Weights:
    """The weights dataclass from its dotted arrays: nested tuples are found by index."""
    values: dict[str, Any] = {}
    for f in dataclasses.fields(kind):
        if f.name not in arrays and f.default is not dataclasses.MISSING:
            continue  # a field added since the file was written: its default
        if f.name in arrays:
            a = arrays[f.name]
            values[f.name] = a.item() if a.ndim == 0 else np.asarray(a, dtype=np.float64)
            continue
        values[f.name] = _nested(f.name, arrays, path)
    return kind(**values)


def _nested(name: str, arrays: dict[str, np.ndarray], path: Path) -> Any:
    children = sorted(
        {int(k[len(name) + 1 :].split(".")[0]) for k in arrays if k.startswith(name + ".")}
    )
    if not children:
        raise ModelLoadError(f"runtime file has no weights named {name!r}", path=path)
    out = []
    for k in children:
        key = f"{name}.{k}"
        if key in arrays:
            out.append(np.asarray(arrays[key], dtype=np.float64))
        else:
            out.append(_nested(key, arrays, path))
    return tuple(out)


def load_runtime(path: str | os.PathLike[str]) -> RuntimeModel:
    """Read a runtime ``.npz``; ModelLoadError names the file and what is wrong."""
    p = Path(path)
    arrays, meta = read_runtime_npz(p, "runtime file")
    if meta.get("format") != FORMAT_VERSION:
        raise ModelLoadError(
            f"runtime format {meta.get('format')!r}, this version reads {FORMAT_VERSION}; "
            "export the checkpoint again",
            path=p,
        )
    arch = str(meta.get("architecture"))
    if arch == "agnostic2d":
        raise ModelLoadError(
            "this is a 2D keypoint model: it lifts keypoints to 3D (convert a keypoint file, "
            "stream --source udp-keypoints://…, both with --keypoint-model), it does not "
            "retarget: give --model a retargeting model, e.g. default (runtimes: "
            f"{', '.join(ARCHITECTURES)})",
            path=p,
        )
    if arch not in ARCHITECTURES:
        raise ModelLoadError(
            f"unknown architecture {arch!r} (runtimes: {', '.join(ARCHITECTURES)})", path=p
        )
    kind = ARCHITECTURES[arch][0]
    try:
        weights = None if kind is None else _read_weights(kind, arrays, p)
    except (TypeError, ValueError) as exc:
        raise ModelLoadError(f"runtime weights do not fit {arch} ({exc})", path=p) from None
    model = RuntimeModel(
        name=str(meta.get("name", p.stem)),
        architecture=arch,
        weights=weights,
        path=p,
        checkpoint_sha256=str(meta.get("checkpoint_sha256", "")),
        data_hash=str(meta.get("data_hash", "")),
        metadata=dict(meta.get("metadata", {})),
    )
    _smoke_test(model)
    return model


def _smoke_test(model: RuntimeModel) -> None:
    """One step on the reference skeleton: weights of the wrong shapes fail here, at load."""
    from robot_retarget.skeleton.canonical import default_canonical_skeleton

    offsets = default_canonical_skeleton().offsets
    rest = np.zeros((len(offsets), 4))
    rest[:, 0] = 1.0
    try:
        model.online(offsets, offsets).step(rest, np.zeros(3))
    except (ValueError, IndexError) as exc:
        raise ModelLoadError(
            f"runtime weights do not fit {model.architecture}: {exc}", path=model.path
        ) from None
