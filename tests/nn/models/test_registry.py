"""Registry: names, paper defaults, helpful errors."""

from __future__ import annotations

import pytest

from robot_retarget.errors import ModelLoadError
from robot_retarget.nn.discriminators import NKNDiscriminator, PMnetDiscriminator
from robot_retarget.nn.models.nkn import NKN
from robot_retarget.nn.models.pmnet import PMnet
from robot_retarget.nn.models.registry import (
    build_discriminator,
    build_model,
    has_discriminator,
    model_names,
)


def test_names() -> None:
    assert model_names() == ("copy", "copy-scaled", "nkn", "pmnet", "residual", "tdcn", "san")
    for name in model_names():
        assert build_model(name).name == name


def test_overrides_and_defaults() -> None:
    model = build_model("nkn", hidden_size=16)
    assert isinstance(model, NKN)
    assert model.config() == {"hidden_size": 16, "num_layers": 2}
    assert isinstance(build_model("pmnet", num_layers=1), PMnet)
    assert isinstance(build_discriminator("nkn"), NKNDiscriminator)
    assert build_discriminator("pmnet").channels == (16, 32, 64, 128)
    assert isinstance(build_discriminator("pmnet"), PMnetDiscriminator)


def test_unknown_name_lists_choices() -> None:
    with pytest.raises(ModelLoadError, match="copy, copy-scaled, nkn, pmnet, residual") as info:
        build_model("no-such-model")
    assert info.value.model == "no-such-model"
    with pytest.raises(ModelLoadError, match="model with a discriminator 'copy'"):
        build_discriminator("copy")
    with pytest.raises(ModelLoadError, match="model with a discriminator 'residual'"):
        build_discriminator("residual")
    assert has_discriminator("nkn")
    assert has_discriminator("pmnet")
    assert has_discriminator("tdcn")
    assert not has_discriminator("residual")


def test_bad_config_key() -> None:
    with pytest.raises(ModelLoadError, match="hidden") as info:
        build_model("nkn", hiden_size=3)
    assert info.value.model == "nkn"
