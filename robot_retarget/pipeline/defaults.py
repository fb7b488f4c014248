"""Which model the product uses when none is named.

The one place to switch the default: :data:`robot_retarget.nn.inference.DEFAULT_MODEL` names
the shipped checkpoint; until that checkpoint exists the pipeline runs :data:`FALLBACK_MODEL`
(the parameter-free ``copy`` baseline), so convert, stream and demo work on a fresh install.
"""

from __future__ import annotations

FALLBACK_MODEL = "copy"


def default_model_name() -> str:
    """The shipped default checkpoint's name if it ships, else the ``copy`` baseline."""
    from robot_retarget.nn.inference import DEFAULT_MODEL, available_models

    return DEFAULT_MODEL if DEFAULT_MODEL in available_models() else FALLBACK_MODEL
