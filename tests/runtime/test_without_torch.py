"""Streaming and converting need no torch: the shipped default runs from its numpy runtime.

Each check runs in a fresh interpreter in which ``import torch`` fails, and compares with the
torch model in this process to 1e-6 rad."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
CLIP = REPO / "tests" / "fixtures" / "motion" / "tiny_walk.bvh"

_NO_TORCH = "import sys\nsys.modules['torch'] = None  # any import of torch now fails\n"

_CONVERT = (
    _NO_TORCH
    + """
import numpy as np, robot_retarget as rr
result = rr.retarget(sys.argv[1], robot="op3")
assert result.model == "default", result.model
assert "torch" not in sys.modules or sys.modules["torch"] is None
np.save(sys.argv[2], result.trajectory.q)
"""
)

_STREAM = (
    _NO_TORCH
    + """
import numpy as np
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sources.replay import ReplaySource

class Clock:
    t = 0.0
    def now(self): return self.t
    def sleep(self, dt): self.t += max(dt, 0.0)

config = load_robot_config("op3")
motion = load_motion(sys.argv[1])
clock = Clock()
step = RetargetStep(config, "default", motion.skeleton)
assert type(step.model).__name__ == "RuntimeModel"
loop = ControlLoop(step, ReplaySource(motion), SimBackend(config, clock=clock.now),
                   LoopSettings(duration_s=1.0), record=True, clock=clock.now, sleep=clock.sleep)
result = loop.run()
assert result.stats.commands > 100
print("streamed", result.stats.commands)
"""
)


def _run(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], cwd=REPO, capture_output=True,
                          text=True, timeout=120, check=False)  # fmt: skip


def test_convert_without_torch_equals_the_torch_model(tmp_path: Path) -> None:
    out = _run(_CONVERT, str(CLIP), str(tmp_path / "q.npy"))
    assert out.returncode == 0, out.stderr
    from robot_retarget.api import retarget
    from robot_retarget.nn.inference import load_model

    with_torch = retarget(CLIP, robot="op3", model=load_model("default")).trajectory.q
    np.testing.assert_allclose(np.load(tmp_path / "q.npy"), with_torch, atol=1e-6)


def test_stream_without_torch() -> None:
    out = _run(_STREAM, str(CLIP))
    assert out.returncode == 0, out.stderr
    assert "streamed" in out.stdout


def test_a_model_without_a_runtime_says_how_to_get_one(tmp_path: Path) -> None:
    code = _NO_TORCH + (
        "from robot_retarget.runtime.loader import load_runtime_model\n"
        "from robot_retarget.errors import ModelLoadError\n"
        "try:\n    load_runtime_model(sys.argv[1])\nexcept ModelLoadError as e:\n"
        "    print(e)\n"
    )
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "best.pt").write_bytes(b"a checkpoint only torch reads")
    out = _run(code, str(tmp_path / "run" / "best.pt"))
    assert "torch is not installed" in out.stdout
    assert "export" in out.stdout
    # A path that is not there is said to be missing: torch would not find it either.
    out = _run(code, str(tmp_path / "gone" / "best.pt"))
    assert "no such file or folder" in out.stdout
    assert "torch" not in out.stdout


def test_a_runtime_file_is_named_as_given(tmp_path: Path) -> None:
    """An exported file was named after the checkpoint it came from ("model best has no foot
    lock" of exp/san.npz)."""
    import shutil

    from robot_retarget.runtime.loader import CHECKPOINT_DIR, load_runtime_model

    mine = tmp_path / "mine.npz"
    shutil.copy(CHECKPOINT_DIR / "default.npz", mine)
    model = load_runtime_model(str(mine))
    assert model.name == str(mine)
