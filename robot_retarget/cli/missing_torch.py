"""The one-line answer when a command needs torch and it is not installed.

``convert``, ``stream``, ``demo``, ``inspect``, ``doctor`` and ``view`` run on the numpy
runtimes without torch; training, evaluation, export and the model benchmark need it. Without
this, those commands (and ``bench --help``, which builds every benchmark's options) ended in an
import traceback.
"""

from __future__ import annotations

from robot_retarget.errors import RetargetError

INSTALL_HINT = (
    "pip install torch==2.13.0 (a CPU build; off the project's machines: pip install torch "
    "--index-url https://download.pytorch.org/whl/cpu)"
)
WITHOUT_TORCH = "convert, stream, demo, inspect, doctor and view run without it"


class MissingTorchError(RetargetError):
    """``what`` needs torch, which cannot be imported (``reason``)."""

    def __init__(self, what: str, reason: str) -> None:
        self.what = what
        self.reason = reason
        super().__init__(
            f"{what} needs torch, which is not installed ({reason}); install it with: "
            f"{INSTALL_HINT}. {WITHOUT_TORCH[0].upper()}{WITHOUT_TORCH[1:]}"
        )


def is_missing_torch(exc: BaseException) -> bool:
    """Whether ``exc`` is torch (or one of its modules) failing to import."""
    name = getattr(exc, "name", None) or ""
    return isinstance(exc, ImportError) and (name == "torch" or name.startswith("torch."))
