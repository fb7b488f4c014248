"""Without the [view] extra the viewer says how to install it; the package never needs it."""

from __future__ import annotations

import subprocess
import sys

import pytest

from robot_retarget.viewer.dependency import INSTALL_HINT, ViewerDependencyError, require_viser


def test_missing_viser_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser now raises ImportError
    with pytest.raises(ViewerDependencyError, match=r"robot-retarget\[view\]") as info:
        require_viser()
    assert info.value.module == "viser"
    assert INSTALL_HINT in str(info.value)


def test_view_without_viser_fails_with_the_hint() -> None:
    code = (
        "import sys; sys.modules['viser'] = None\n"
        "from robot_retarget.cli.main import main\n"
        "raise SystemExit(main(['view', 'missing.npz', '--no-browser']))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 1
    assert 'pip install "robot-retarget[view]"' in done.stderr


def test_the_viewer_modules_import_without_viser() -> None:
    code = (
        "import sys; import robot_retarget.viewer.trajectory_page, robot_retarget.cli.view_cmd\n"
        "assert 'viser' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
