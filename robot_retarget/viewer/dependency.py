"""The viewer's one optional dependency, imported only when a page is served."""

from __future__ import annotations

import importlib
from types import ModuleType

from robot_retarget.errors import RetargetError

INSTALL_HINT = 'pip install "robot-retarget[view]" (from a checkout: pip install -e ".[view]")'


class ViewerDependencyError(RetargetError):
    """viser (the ``[view]`` extra) is not installed; ``module`` is what failed to import."""

    def __init__(self, module: str, reason: str) -> None:
        self.module = module
        self.reason = reason
        super().__init__(
            f"the browser viewer needs {module}, which cannot be imported ({reason}); install "
            f"it with: {INSTALL_HINT}"
        )


def require_viser() -> ModuleType:
    """Import and return viser, or raise :class:`ViewerDependencyError` saying how to get it."""
    try:
        return importlib.import_module("viser")
    except ImportError as exc:
        raise ViewerDependencyError("viser", str(exc)) from None
