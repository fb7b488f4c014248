"""The character-agnostic 2D model as ``convert`` and ``stream`` run it: numpy only.

Same arithmetic as the torch model (robot_retarget.nn.models.agnostic2d; tested to float32
rounding): whole clips with :meth:`Agnostic2DRuntime.run_clip` (``causal=False`` pools the
static encoders over the whole clip: ``convert``, which runs the shipped centred model
``agnostic2d_clip``, whose motion convolutions also see the frames after each one), and one
frame at a time (causal models only) with
:class:`MirrorAveragedStep` (causal, the image and its mirror: ``stream``) or
:class:`Agnostic2DStep` (the image alone). Both take COCO-17 keypoints with their visibility
and return the 22 canonical local rotations (w-x-y-z), the root's in the camera's heading frame.

File format (``.npz``, written by ``train --model agnostic2d``): one array per weight under a
dotted name (``motion.0.0`` = first motion layer's kernel, ``motion.0.1`` its bias) and
``__meta__`` (JSON: ``format``, ``architecture`` = "agnostic2d", ``name``,
``checkpoint_sha256``, ``data_hash``, ``metadata``), the conventions of
:mod:`robot_retarget.runtime.model`. An ensemble (``export`` of several checkpoints, answers
averaged) is format 2: its first model's arrays as above, model i's (i ≥ 1) under
``ensemble.i.``, ``members`` (the count) in ``__meta__``, and each model's checkpoint file,
sha256, step and training command in ``metadata["ensemble"]``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, TypeVar

import numpy as np

from robot_retarget.array_types import BoolArray, Float32Array, FloatArray
from robot_retarget.casadi_jit import CompiledFunction
from robot_retarget.errors import ModelLoadError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.coco17 import FLIP_PAIRS, NUM_KEYPOINTS
from robot_retarget.keypoints.normalize import (
    FEATURES_PER_FRAME,
    KeypointNormalizer,
    normalize_sequences,
)
from robot_retarget.runtime.agnostic2d_graph import (
    answer_function,
    features_function,
    initial_state,
)
from robot_retarget.runtime.frame import f32_layer
from robot_retarget.runtime.npz_file import read_runtime_npz, write_runtime_npz
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS
from robot_retarget.skeleton.mirror import mirror_rotations, swap_index

ARCHITECTURE = "agnostic2d"
FORMAT_VERSION = 1
ENSEMBLE_FORMAT_VERSION = 2
_J = len(CANONICAL_JOINTS)
_SLOPE = 0.2
Conv = tuple[FloatArray, FloatArray]  # kernel (out, in, k), bias (out,)


@dataclass(frozen=True)
class Agnostic2DWeights:
    """Convolution kernels and biases of every layer (see the torch model for the roles)."""

    dilations: tuple[float, ...]
    motion: tuple[Conv, ...]
    skeleton: tuple[Conv, Conv, Conv]
    view: tuple[Conv, Conv, Conv]
    head: tuple[Conv, Conv]
    centered: bool = False  # the motion convolutions look ahead: whole clips only (convert)

    def arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """Named arrays of the file (``prefix``: an ensemble member's, see the module)."""
        out: dict[str, np.ndarray] = {
            f"{prefix}dilations": np.asarray(self.dilations, dtype=np.float64)
        }
        if self.centered:  # absent in causal files, as before this option
            out[f"{prefix}centered"] = np.ones(1)
        for group in ("motion", "skeleton", "view", "head"):
            for i, (w, b) in enumerate(getattr(self, group)):
                out[f"{prefix}{group}.{i}.0"] = np.asarray(w, dtype=np.float32)
                out[f"{prefix}{group}.{i}.1"] = np.asarray(b, dtype=np.float32)
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], prefix: str = "") -> Agnostic2DWeights:
        def group(name: str) -> tuple[Conv, ...]:
            out = []
            i = 0
            while f"{prefix}{name}.{i}.0" in arrays:
                w = np.asarray(arrays[f"{prefix}{name}.{i}.0"], dtype=np.float64)
                b = np.asarray(arrays[f"{prefix}{name}.{i}.1"], dtype=np.float64)
                out.append((w, b))
                i += 1
            return tuple(out)

        if f"{prefix}dilations" not in arrays:
            raise KeyError(f"{prefix}dilations")
        dil = tuple(float(d) for d in np.asarray(arrays[f"{prefix}dilations"]).ravel())
        motion, skel, view, head = group("motion"), group("skeleton"), group("view"), group("head")
        if len(motion) != len(dil) or len(skel) != 3 or len(view) != 3 or len(head) != 2:
            raise ValueError(
                f"layer counts motion {len(motion)} (dilations {len(dil)}), skeleton "
                f"{len(skel)}/3, view {len(view)}/3, head {len(head)}/2"
            )
        key = f"{prefix}centered"
        centered = key in arrays and bool(np.asarray(arrays[key]).ravel()[0])
        return cls(
            dil,
            motion,
            (skel[0], skel[1], skel[2]),
            (view[0], view[1], view[2]),
            (head[0], head[1]),
            centered,
        )


_KEYPOINT_MIRROR = swap_index(list(FLIP_PAIRS), NUM_KEYPOINTS)
_LOOKS_AHEAD = (
    "this keypoint model looks ahead (trained with centered=true): it lifts whole clips "
    "(convert), not a live stream; stream with a causal one such as the shipped agnostic2d"
)


_A = TypeVar("_A", FloatArray, Float32Array)


def _lrelu(x: _A) -> _A:
    out: _A = np.maximum(x, _SLOPE * x)  # the slope is under 1: max(x, 0.2 x) is LReLU
    return out


def rotation_6d_to_quat(d6: FloatArray) -> FloatArray:
    """(…, 6) → unit quaternions (…, 4), Gram–Schmidt as the torch model."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = a1 / np.maximum(np.sqrt((a1 * a1).sum(-1, keepdims=True)), 1e-12)
    a2 = a2 - (b1 * a2).sum(-1, keepdims=True) * b1
    b2 = a2 / np.maximum(np.sqrt((a2 * a2).sum(-1, keepdims=True)), 1e-12)
    x1, y1, z1 = b1[..., 0], b1[..., 1], b1[..., 2]
    x2, y2, z2 = b2[..., 0], b2[..., 1], b2[..., 2]
    # b3 = b1 × b2; the matrix has columns b1, b2, b3 (m_rc = column c's row r).
    x3, y3, z3 = y1 * z2 - z1 * y2, z1 * x2 - x1 * z2, x1 * y2 - y1 * x2
    trace = x1 + y2 + z3
    # Where w ≥ 0.35 the direct formula is well conditioned; elsewhere the largest pivot
    # (Shepperd), chosen per rotation as the stream's compiled graph chooses (a degenerate 6D
    # pair, whose matrix is singular, gets a different answer from each formula: choosing for
    # the whole array at once made one joint's answer depend on the others').
    well = trace > -0.5
    w = 0.5 * np.sqrt(np.maximum(1.0 + trace, 1e-12))
    f = 0.25 / w
    q = np.stack([w, (z2 - y3) * f, (x3 - z1) * f, (y1 - x2) * f], axis=-1)
    out: FloatArray = q / np.sqrt((q * q).sum(-1, keepdims=True))
    if np.all(well):
        return out
    m = np.stack([b1, b2, np.stack([x3, y3, z3], -1)], -1)
    return np.where(well[..., None], out, quat.normalize(quat.from_matrix(m)))


def _pointwise(x: FloatArray, conv: Conv) -> FloatArray:
    """1 × 1 convolution of (C, T) or (C,)."""
    w, b = conv
    if x.ndim == 1:
        r: FloatArray = w[:, :, 0] @ x + b
        return r
    r = w[:, :, 0] @ x + b[:, None]
    return r


def _dense(conv: Conv) -> tuple[Float32Array, Float32Array]:
    """A 1 × 1 convolution as a float32 matrix and column bias (the stream step's layers)."""
    w, b = conv
    return f32_layer((w[:, :, 0], b[:, None]))


def _dense_apply(layer: tuple[Float32Array, Float32Array], x: Float32Array) -> Float32Array:
    w, b = layer
    out: Float32Array = w @ x + b
    return out


class KeypointStep(Protocol):
    """The causal keypoint model one camera frame at a time (what ``stream`` runs)."""

    def reset(self) -> None: ...

    def step(self, xy: FloatArray, valid: BoolArray) -> FloatArray:
        """COCO-17 pixels (17, 2) (NaN where invalid) and visibility (17,) → (22, 4)."""
        ...


def _run_weights(w: Agnostic2DWeights, features: FloatArray, *, causal: bool) -> FloatArray:
    """One model's answer: features (T, 51) → local rotations (T, 22, 4)."""
    if causal and w.centered:
        raise ValueError(_LOOKS_AHEAD)
    x = np.asarray(features, dtype=np.float64).T  # (C, T)
    t = x.shape[1]
    h = x
    for (kern, bias), d_f in zip(w.motion, w.dilations, strict=True):
        d = int(d_f)
        k = kern.shape[2]
        span = (k - 1) * d
        before, after = (span // 2, span // 2) if w.centered else (span, 0)
        c = h.shape[0]
        hp = np.concatenate([np.zeros((c, before)), h, np.zeros((c, after))], axis=1)
        acc = np.repeat(bias[:, None], t, axis=1)
        for i in range(k):
            acc = acc + kern[:, :, i] @ hp[:, i * d : i * d + t]
        h = _lrelu(acc)
    codes = [h]
    for enc in (w.skeleton, w.view):
        s = _lrelu(_pointwise(_lrelu(_pointwise(x, enc[0])), enc[1]))
        if causal:
            pooled = np.cumsum(s, axis=1) / np.arange(1, t + 1)
        else:
            pooled = np.repeat(s.mean(axis=1, keepdims=True), t, axis=1)
        codes.append(_pointwise(pooled, enc[2]))
    z = np.concatenate(codes, axis=0)
    out = _pointwise(_lrelu(_pointwise(z, w.head[0])), w.head[1]).T
    return rotation_6d_to_quat(out.reshape(t, _J, 6))


def mean_rotation(answers: list[FloatArray]) -> FloatArray:
    """The normalised mean of several (..., 22, 4) answers, each turned to the first one's
    hemisphere (the chordal mean of rotations a few degrees apart)."""
    first = answers[0]
    total = np.array(first, dtype=np.float64)
    for q in answers[1:]:
        total += np.where(((first * q).sum(-1) < 0.0)[..., None], -q, q)
    return quat.normalize(total)


@dataclass(frozen=True)
class Agnostic2DRuntime:
    """A trained keypoint model ready to run (weights and provenance).

    ``ensemble``: further models of the same kind (trained from other seeds) whose answers are
    averaged with ``weights``' — several models' errors partly cancel. Whole clips only
    (``convert``): :meth:`online` refuses an ensemble."""

    weights: Agnostic2DWeights
    name: str = ARCHITECTURE
    path: Path | None = None
    checkpoint_sha256: str = ""
    data_hash: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)
    ensemble: tuple[Agnostic2DWeights, ...] = ()

    def __post_init__(self) -> None:
        if any(m.centered != self.weights.centered for m in self.ensemble):
            raise ValueError("an ensemble's models must all be centred or all causal")

    @property
    def members(self) -> tuple[Agnostic2DWeights, ...]:
        """Every model whose answer is averaged: ``weights`` first."""
        return (self.weights, *self.ensemble)

    @property
    def receptive_field(self) -> int:
        return max(1 + (m.motion[0][0].shape[2] - 1) * int(sum(m.dilations)) for m in self.members)

    @property
    def centered(self) -> bool:
        """Whether the model looks ahead (whole clips only: ``convert``, never ``stream``)."""
        return self.weights.centered

    def run_features(self, features: FloatArray, *, causal: bool) -> FloatArray:
        """Features (T, 51) → local rotations (T, 22, 4), the members' answers averaged
        (``causal`` with a centred model: ModelLoadError, as :meth:`online`)."""
        if causal and self.centered:
            raise ModelLoadError(_LOOKS_AHEAD, path=self.path, model=self.name)
        answers = [_run_weights(m, features, causal=causal) for m in self.members]
        return answers[0] if len(answers) == 1 else mean_rotation(answers)

    def run_clip(
        self, xy: FloatArray, valid: BoolArray, *, causal: bool, mirror_average: bool = False
    ) -> FloatArray:
        """COCO-17 pixels (T, 17, 2) and visibility (T, 17) → local rotations (T, 22, 4).

        ``mirror_average``: also run the left-right mirrored image and average its mirrored
        answer with the direct one (test-time augmentation; ``convert`` uses it: 9.4° → 8.9°
        lifted-pose error on validation clips, and ``stream`` through :meth:`online`). The
        result is exactly mirror-symmetric."""
        v = np.asarray(valid, dtype=bool)
        p = np.asarray(xy, dtype=np.float64)
        feats = normalize_sequences(p[None], v[None])[0]
        direct = self.run_features(feats, causal=causal)
        if not mirror_average:
            return direct
        flipped, flipped_valid = mirror_image(p, v)
        mirrored_feats = normalize_sequences(flipped[None], flipped_valid[None])[0]
        return average_with_mirrored(direct, self.run_features(mirrored_feats, causal=causal))

    def online(self, *, mirror_average: bool = True) -> KeypointStep:
        """The causal step for ``stream``; ``mirror_average`` (default) also steps the mirrored
        image, as ``run_clip(causal=True, mirror_average=True)``: twice the arithmetic, 0.7°
        less lifted-pose error on the validation clips (11.6° → 10.9°). An ensemble of causal
        models steps each and averages their answers, as :meth:`run_features`. A centred
        model has no step (ModelLoadError)."""
        if self.centered:
            raise ModelLoadError(_LOOKS_AHEAD, path=self.path, model=self.name)
        if mirror_average:
            return MirrorAveragedStep(self.weights, ensemble=self.ensemble)
        return Agnostic2DStep(self.weights, ensemble=self.ensemble)


def mirror_image(xy: FloatArray, valid: BoolArray) -> tuple[FloatArray, BoolArray]:
    """COCO-17 pixels (..., 17, 2) and visibility (..., 17) of the left-right mirrored image
    (x negated: the features are normalised, so no image width is needed)."""
    flipped = np.array(xy[..., _KEYPOINT_MIRROR, :], dtype=np.float64)
    flipped[..., 0] *= -1.0
    return flipped, np.asarray(valid[..., _KEYPOINT_MIRROR], dtype=bool)


def average_with_mirrored(direct: FloatArray, from_mirrored: FloatArray) -> FloatArray:
    """The mean rotation of ``direct`` and the mirror of the mirrored image's answer (both
    (..., 22, 4)); exactly mirror-symmetric in the image."""
    return mean_rotation([direct, mirror_rotations(from_mirrored)])


class _StreamSteps:
    """One causal model's dense layers one frame at a time for ``streams`` independent streams
    at once (the callers compute the features): each layer is one matrix product on a column
    per stream (the mirrored image rides along for little more than the cost of one)."""

    def __init__(self, weights: Agnostic2DWeights, streams: int) -> None:
        if weights.centered:
            raise ValueError(_LOOKS_AHEAD)
        self._streams = streams
        # In float32, the precision the weights were trained and stored in: a frame's products
        # are matrix-vector ones, bound by reading the weights, so half the bytes is about
        # half the time (192 channels: 30 → 10 µs per motion layer).
        self._layers: list[tuple[Float32Array, Float32Array, int]] = []
        for kern, bias in weights.motion:
            out_c, in_c, k = kern.shape
            # Columns ordered (input channel, tap) to match buffer[:, ::d] flattened per stream.
            self._layers.append((*f32_layer((kern.reshape(out_c, in_c * k), bias[:, None])), k))
        self._static = [[_dense(c) for c in enc] for enc in (weights.skeleton, weights.view)]
        self._head = [_dense(c) for c in weights.head]
        self._dil = [int(d) for d in weights.dilations]
        self.reset()

    def reset(self) -> None:
        b = self._streams
        self._buffers = [
            np.zeros((flat.shape[1] // k, (k - 1) * d + 1, b), dtype=np.float32)
            for (flat, _b, k), d in zip(self._layers, self._dil, strict=True)
        ]
        self._sums = [np.zeros((enc[1][0].shape[0], b), dtype=np.float32) for enc in self._static]
        self._count = 0

    def step_features(self, features: FloatArray) -> FloatArray:
        """One frame's features (B, 51) → local rotations (B, 22, 4)."""
        out = self.head_outputs(features)
        return rotation_6d_to_quat(np.asarray(out, dtype=np.float64).reshape(-1, _J, 6))

    def head_outputs(self, features: FloatArray) -> Float32Array:
        """One frame's features (B, 51) → the head's 6D rotations (B, 22·6), float32."""
        x = np.asarray(features, dtype=np.float32).T  # (51, B)
        h = x
        for (flat, bias, _k), d, buf in zip(self._layers, self._dil, self._buffers, strict=True):
            buf[:, :-1] = buf[:, 1:]
            buf[:, -1] = h
            taps = buf[:, ::d]
            h = _lrelu(flat @ taps.reshape(-1, taps.shape[-1]) + bias)
        self._count += 1
        codes = [h]
        for (l1, l2, code), total in zip(self._static, self._sums, strict=True):
            total += _lrelu(_dense_apply(l2, _lrelu(_dense_apply(l1, x))))
            codes.append(_dense_apply(code, total * np.float32(1.0 / self._count)))
        z = np.concatenate(codes)
        h1, h2 = self._head
        out: Float32Array = _dense_apply(h2, _lrelu(_dense_apply(h1, z))).T  # (B, 22·6)
        return out


class Agnostic2DStep:
    """The causal model one frame at a time: ``step(xy (17, 2), valid (17,)) → (22, 4)``
    (``ensemble``: further causal models, their answers averaged, as ``run_features``)."""

    def __init__(
        self, weights: Agnostic2DWeights, *, ensemble: Sequence[Agnostic2DWeights] = ()
    ) -> None:
        self._steps = [_StreamSteps(w, 1) for w in (weights, *ensemble)]
        self._normalizer = KeypointNormalizer(1)

    def reset(self) -> None:
        self._normalizer.reset()
        for steps in self._steps:
            steps.reset()

    def step_features(self, features: FloatArray) -> FloatArray:
        """One frame's features (51,) → local rotations (22, 4)."""
        x = np.asarray(features, dtype=np.float64)[None]
        answers = [steps.step_features(x)[0] for steps in self._steps]
        return answers[0] if len(answers) == 1 else mean_rotation(answers)

    def step(self, xy: FloatArray, valid: BoolArray) -> FloatArray:
        """COCO-17 pixels (17, 2) (NaN where invalid) and visibility (17,) → (22, 4)."""
        v = np.asarray(valid, dtype=bool).reshape(1, NUM_KEYPOINTS)
        features = self._normalizer.step(np.asarray(xy, dtype=np.float64)[None], v)
        return self.step_features(features[0])


class MirrorAveragedStep:
    """The causal step on the image and on its mirror (two streams, one product per layer),
    answers averaged: the frame-by-frame twin of ``run_clip(causal=True,
    mirror_average=True)`` (``ensemble``: further causal models, every model's answers
    averaged as ``run_clip`` does). The features before the dense layers and the rotations
    after them run as two compiled calls (robot_retarget.runtime.agnostic2d_graph);
    ``compiled=False`` runs the numpy reference instead."""

    def __init__(
        self,
        weights: Agnostic2DWeights,
        *,
        ensemble: Sequence[Agnostic2DWeights] = (),
        compiled: bool = True,
    ) -> None:
        self._members = [_StreamSteps(w, 2) for w in (weights, *ensemble)]
        self._normalizer = KeypointNormalizer(2)
        self._calls = _MirrorStepCalls(len(self._members)) if compiled else None

    def reset(self) -> None:
        self._normalizer.reset()
        for steps in self._members:
            steps.reset()
        if self._calls is not None:
            self._calls.state[:] = initial_state()

    def step(self, xy: FloatArray, valid: BoolArray) -> FloatArray:
        """COCO-17 pixels (17, 2) (NaN where invalid) and visibility (17,) → (22, 4)."""
        p = np.asarray(xy, dtype=np.float64)
        v = np.asarray(valid, dtype=bool)
        g = self._calls
        if g is not None:
            g.xy[:] = np.where(v[:, None], p, 0.0).reshape(-1)
            g.seen[:] = v
            g.features()
            g.state[:] = g.next_state
            features = g.both.reshape(2, FEATURES_PER_FRAME)
            for m, steps in enumerate(self._members):
                g.heads[m] = steps.head_outputs(features)
            g.answer()
            return g.local.reshape(_J, 4).copy()
        flipped, flipped_valid = mirror_image(p, v)
        features = self._normalizer.step(np.stack([p, flipped]), np.stack([v, flipped_valid]))
        answers = [steps.step_features(features) for steps in self._members]
        if len(answers) == 1:
            direct, mirrored = answers[0]
        else:  # each image's answers averaged over the models, then the two (as run_clip)
            direct = mean_rotation([a[0] for a in answers])
            mirrored = mean_rotation([a[1] for a in answers])
        return average_with_mirrored(direct, mirrored)


class _MirrorStepCalls:
    """The two compiled graphs of the mirrored step of ``members`` models, arrays bound once."""

    def __init__(self, members: int) -> None:
        self.features = CompiledFunction(features_function())
        self.xy, self.seen, self.state = self.features.args
        self.both, self.next_state = self.features.res
        self.state[:] = initial_state()
        self.answer = CompiledFunction(answer_function(members))
        (head,) = self.answer.args
        self.heads = head.reshape(members, 2, _J * 6)  # a view: writes land in the bound array
        (self.local,) = self.answer.res


def save_agnostic2d(model: Agnostic2DRuntime, path: str | os.PathLike[str]) -> Path:
    """Write a runtime ``.npz`` (see the module docstring)."""
    out = Path(path)
    arrays: dict[str, np.ndarray] = {}
    for i, member in enumerate(model.members):
        arrays.update(member.arrays(_member_prefix(i)))
    meta = {
        # An ensemble is format 2, so that a version of the package that predates ensembles
        # refuses it rather than running its first model alone.
        "format": ENSEMBLE_FORMAT_VERSION if model.ensemble else FORMAT_VERSION,
        "members": len(model.members),
        "architecture": ARCHITECTURE,
        "name": model.name,
        "checkpoint_sha256": model.checkpoint_sha256,
        "data_hash": model.data_hash,
        "metadata": model.metadata,
    }
    return write_runtime_npz(out, arrays, meta)


def load_agnostic2d(path: str | os.PathLike[str]) -> Agnostic2DRuntime:
    """Read a runtime ``.npz``; ModelLoadError names the file and what is wrong."""
    p = Path(path)
    arrays, meta = read_runtime_npz(p, "keypoint model file")
    formats = (FORMAT_VERSION, ENSEMBLE_FORMAT_VERSION)
    if meta.get("architecture") != ARCHITECTURE or meta.get("format") not in formats:
        raise ModelLoadError(
            f"not an {ARCHITECTURE} runtime of format {' or '.join(map(str, formats))} (found "
            f"{meta.get('architecture')!r}, format {meta.get('format')!r}); the keypoint model "
            "is trained with train --model agnostic2d",
            path=p,
        )
    count = meta.get("members", 1)
    if not isinstance(count, int) or count < 1:
        raise ModelLoadError(f"runtime metadata gives {count!r} members (≥ 1 expected)", path=p)
    try:
        members = [Agnostic2DWeights.from_arrays(arrays, _member_prefix(i)) for i in range(count)]
        model = Agnostic2DRuntime(
            members[0],
            name=str(meta.get("name", p.stem)),
            path=p,
            checkpoint_sha256=str(meta.get("checkpoint_sha256", "")),
            data_hash=str(meta.get("data_hash", "")),
            metadata=dict(meta.get("metadata", {})),
            ensemble=tuple(members[1:]),
        )
    except (KeyError, ValueError) as exc:
        raise ModelLoadError(f"runtime weights do not fit {ARCHITECTURE} ({exc})", path=p) from None
    try:  # wrong shapes fail here, at load, not in the live loop
        for weights in members:
            if weights.centered:
                _run_weights(weights, np.zeros((2, FEATURES_PER_FRAME)), causal=False)
            else:
                Agnostic2DStep(weights).step_features(np.zeros(FEATURES_PER_FRAME))
    except (ValueError, IndexError) as exc:
        raise ModelLoadError(f"runtime weights do not fit {ARCHITECTURE}: {exc}", path=p) from None
    return model


def _member_prefix(i: int) -> str:
    """Array-name prefix of an ensemble's model ``i`` (none for the first: a single model's
    file is an ensemble's first model)."""
    return f"ensemble.{i}." if i else ""


_CHECKPOINTS = Path(__file__).resolve().parent.parent / "data" / "checkpoints"
SHIPPED_KEYPOINT_MODEL = _CHECKPOINTS / "agnostic2d.npz"
"""The causal keypoint model: ``stream`` (and the 2D demo)."""
SHIPPED_CLIP_KEYPOINT_MODEL = _CHECKPOINTS / "agnostic2d_clip.npz"
"""The centred keypoint model: ``convert`` (whole clips; it sees a second ahead of each frame)."""
CLIP_MODEL_NAME = "agnostic2d_clip"


def load_keypoint_model(
    name_or_path: str | os.PathLike[str] | None = None, *, whole_clip: bool = False
) -> Agnostic2DRuntime:
    """A keypoint model by name — ``agnostic2d`` (the shipped causal one) or
    ``agnostic2d_clip`` (the shipped centred one) — or a runtime ``.npz`` by path; None: the
    shipped one for the use (``whole_clip``: ``convert``'s, else ``stream``'s)."""
    if name_or_path is None:
        name_or_path = CLIP_MODEL_NAME if whole_clip else ARCHITECTURE
    return load_agnostic2d(keypoint_model_path(name_or_path))


def keypoint_model_path(name_or_path: str | os.PathLike[str]) -> Path:
    """The file a keypoint model's name or path stands for; ModelLoadError naming the shipped
    ones if it is neither (``convert`` asks before any clip is read)."""
    shipped = {ARCHITECTURE: SHIPPED_KEYPOINT_MODEL, CLIP_MODEL_NAME: SHIPPED_CLIP_KEYPOINT_MODEL}
    path = Path(shipped.get(os.fspath(name_or_path), name_or_path))
    if not path.is_file():
        raise ModelLoadError(
            f"no keypoint model {os.fspath(name_or_path)!r}: not {ARCHITECTURE} or "
            f"{CLIP_MODEL_NAME} (the shipped ones) nor a runtime .npz file"
        )
    return path
