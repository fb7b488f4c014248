"""Which model the product uses when none is named.

The one place to switch the default: :data:`DEFAULT_MODEL` names
the shipped checkpoint; until that checkpoint exists the pipeline runs :data:`FALLBACK_MODEL`,
so convert, stream and demo work on a fresh install. ``copy-scaled`` (rotations copied, root
velocity scaled by the height ratio) is the stronger of the parameter-free baselines: the same
joint rotations as ``copy``, but its root path fits the target's size (foot skate 0.22 vs 1.13 leg
lengths/s on the validation subjects, ``python launch.py eval``).
"""

from __future__ import annotations

FALLBACK_MODEL = "copy-scaled"


DEFAULT_MODEL = "default"

MODEL_HELP = (
    "a model name such as default or copy-scaled, a runtime .npz written by export, a .pt "
    "checkpoint or a training run folder (omitted: the shipped model 'default'; copy-scaled "
    "where it is not installed)"
)
"""``--model``'s help wherever the model goes through load_runtime_model."""


def default_model_name() -> str:
    """The shipped default model's name if it ships (its numpy runtime or its checkpoint),
    else :data:`FALLBACK_MODEL`. Imports no torch."""
    from robot_retarget.runtime.loader import CHECKPOINT_DIR

    shipped = any((CHECKPOINT_DIR / f"{DEFAULT_MODEL}{ext}").is_file() for ext in (".npz", ".pt"))
    return DEFAULT_MODEL if shipped else FALLBACK_MODEL
