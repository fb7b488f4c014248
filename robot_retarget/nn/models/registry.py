"""Model names → classes, with the papers' hyper-parameters as defaults.

``build_model("nkn")`` gives NKN as published (2 × 512 GRUs); keyword arguments override the
constructor's defaults (tests use tiny hidden sizes). ``build_discriminator`` gives the
discriminator a trainable model is trained against.
"""

from __future__ import annotations

import inspect
from typing import Any

from torch import nn

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn.discriminators import NKNDiscriminator, PMnetDiscriminator
from robot_retarget.nn.models.agnostic2d import Agnostic2D
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.copy import CopyModel, CopyScaledModel
from robot_retarget.nn.models.nkn import NKN
from robot_retarget.nn.models.pmnet import PMnet
from robot_retarget.nn.models.residual import ResidualRetargeter
from robot_retarget.nn.models.san import SAN
from robot_retarget.nn.models.tdcn import TDCN
from robot_retarget.nn.patch_discriminator import PatchDiscriminator

MODELS: dict[str, type[RetargetModel]] = {
    cls.name: cls for cls in (CopyModel, CopyScaledModel, NKN, PMnet, ResidualRetargeter, TDCN, SAN)
}

# Models of 2D keypoints (not RetargetModels: their input is pixels, not rotations); trained
# by robot_retarget.nn.agnostic2d_training, run by robot_retarget.runtime.agnostic2d.
KEYPOINT_MODELS: dict[str, type[Agnostic2D]] = {Agnostic2D.name: Agnostic2D}

DISCRIMINATORS: dict[str, type[nn.Module]] = {
    NKN.name: NKNDiscriminator,
    PMnet.name: PMnetDiscriminator,
    TDCN.name: PatchDiscriminator,
    SAN.name: PatchDiscriminator,
}


def model_names() -> tuple[str, ...]:
    """Names accepted by :func:`build_model`, e.g. for a CLI ``choices=``."""
    return tuple(MODELS)


def _lookup(name: str, table: dict[str, Any], what: str) -> Any:
    try:
        return table[name]
    except KeyError:
        raise ModelLoadError(
            f"unknown {what} {name!r}; choose one of {', '.join(sorted(table))}", model=name
        ) from None


def model_class(name: str) -> type[RetargetModel]:
    """The model class registered as ``name``; ModelLoadError for an unknown name."""
    cls: type[RetargetModel] = _lookup(name, MODELS, "model")
    return cls


def build_model(name: str, **config: Any) -> RetargetModel:
    """A fresh model by name; ``config`` overrides the constructor's (paper) defaults.

    Raises ModelLoadError for an unknown name or configuration key.
    """
    cls = model_class(name)
    allowed = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    unknown = sorted(set(config) - set(allowed))
    if unknown:
        raise ModelLoadError(
            f"unknown configuration key(s) {unknown} for model {name!r}; "
            f"allowed: {', '.join(allowed) or 'none'}",
            model=name,
        )
    try:
        return cls(**config)
    except TypeError as exc:
        raise ModelLoadError(
            f"bad configuration {config!r} for model {name!r}: {exc}", model=name
        ) from exc


def has_discriminator(model_name: str) -> bool:
    """Whether ``model_name`` is trained against a discriminator (NKN, PMnet, TDCN, SAN)."""
    return model_name in DISCRIMINATORS


def build_discriminator(model_name: str, **config: Any) -> nn.Module:
    """The discriminator a model is trained against (raises for models without one)."""
    cls: type[nn.Module] = _lookup(model_name, DISCRIMINATORS, "model with a discriminator")
    return cls(**config)
