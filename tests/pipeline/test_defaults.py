from __future__ import annotations

from robot_retarget.nn.inference import DEFAULT_MODEL, available_models, load_model
from robot_retarget.pipeline.defaults import FALLBACK_MODEL, default_model_name


def test_default_model_is_the_shipped_checkpoint_or_copy() -> None:
    expected = DEFAULT_MODEL if DEFAULT_MODEL in available_models() else FALLBACK_MODEL
    assert default_model_name() == expected
    assert load_model(default_model_name()).name == default_model_name()
