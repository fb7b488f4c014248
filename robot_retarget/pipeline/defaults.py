"""Which model the product uses when none is named.

The one place to switch the default: :data:`robot_retarget.nn.inference.DEFAULT_MODEL` names
the shipped checkpoint; until that checkpoint exists the pipeline runs :data:`FALLBACK_MODEL`,
so convert, stream and demo work on a fresh install. ``copy-scaled`` (rotations copied, root
velocity scaled by the height ratio) is the stronger of the parameter-free baselines: the same
joint rotations as ``copy``, but its root path fits the target's size (foot skate 0.22 vs 1.13 leg
lengths/s on the validation subjects, ``python launch.py eval``).
"""

from __future__ import annotations

FALLBACK_MODEL = "copy-scaled"


def default_model_name() -> str:
    """The shipped default checkpoint's name if it ships, else :data:`FALLBACK_MODEL`."""
    from robot_retarget.nn.inference import DEFAULT_MODEL, available_models

    return DEFAULT_MODEL if DEFAULT_MODEL in available_models() else FALLBACK_MODEL
