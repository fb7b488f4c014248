"""The public API: lazy (no torch or casadi on import), complete; three lines retarget a clip."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import robot_retarget as rr

REPO = Path(__file__).resolve().parents[1]
CLIP = REPO / "tests" / "fixtures" / "motion" / "tiny_walk.bvh"


def test_import_loads_neither_torch_nor_casadi() -> None:
    code = (
        "import sys, robot_retarget\n"
        "heavy = [m for m in ('torch', 'casadi', 'dynamixel_sdk', 'serial') if m in sys.modules]\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_every_exported_name_resolves() -> None:
    assert set(rr.__all__) == {"__version__", *rr._EXPORTS}
    for name in rr._EXPORTS:
        assert getattr(rr, name) is not None, name
    assert "retarget" in dir(rr)


def test_unknown_names_raise_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no_such_thing"):
        rr.no_such_thing  # type: ignore[attr-defined]  # noqa: B018


def test_three_lines_retarget_a_clip(tmp_path: Path) -> None:
    result = rr.retarget(CLIP, robot="op3")
    out = result.trajectory.write(tmp_path / "walk_op3.npz")
    traj = rr.RobotTrajectory.read(out)
    config = rr.load_robot("op3")
    assert traj.joint_names == config.joint_names
    assert traj.fps == config.control_rate_hz
    assert result.report.limits.ok
    assert result.model == "default"
    # Not the init pose held still: the robot moves with the clip.
    assert float(np.ptp(traj.q, axis=0).max()) > 0.1


def test_retarget_takes_a_loaded_motion_robot_and_model() -> None:
    motion = rr.load_motion(CLIP)
    config = rr.load_robot("poppy_humanoid")
    result = rr.retarget(motion, robot=config, model=rr.load_model("copy"), fps=25.0)
    assert result.trajectory.fps == 25.0
    assert result.model == "copy"
    assert result.report.limits.ok


def test_api_errors_are_retarget_errors_that_name_what_is_wrong(tmp_path: Path) -> None:
    for fps in (0.0, -5.0, float("nan"), "30", True, 1e9):
        with pytest.raises(rr.RetargetError, match="fps must be a frame rate, 1–1000"):
            rr.retarget(CLIP, fps=fps)  # type: ignore[arg-type]
    assert rr.retarget(CLIP, fps=np.float32(30.0)).trajectory.fps == 30.0  # numpy numbers too
    motion = rr.load_motion(CLIP)
    bad = motion.local_quats.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(rr.RetargetError, match="must be finite") as info:
        dataclasses.replace(motion, local_quats=bad)  # a HumanMotion built by hand
    assert isinstance(info.value, ValueError)  # what it raised before, still caught as such
    with pytest.raises(rr.RetargetError, match="fps must be positive"):
        dataclasses.replace(motion, fps=0.0)
    with pytest.raises(rr.RetargetError, match="robot must be a name"):
        rr.retarget(CLIP, robot=None)  # type: ignore[arg-type]
    with pytest.raises(rr.RetargetError, match="a folder; retarget takes one clip"):
        rr.retarget(tmp_path)
    empty = tmp_path / "empty.bvh"
    empty.write_bytes(b"")
    with pytest.raises(rr.RetargetError, match="the file is empty"):
        rr.retarget(empty)
    empty.unlink()
    traj = rr.retarget(CLIP).trajectory
    missing = tmp_path / "no" / "x.npz"
    with pytest.raises(rr.RetargetError, match="create it first"):
        traj.write(missing)
    out = traj.write(tmp_path / "x.npz")
    with pytest.raises(rr.RetargetError, match="overwrite=True"):
        traj.write(out)  # running the README's example twice says how to replace the file
    assert traj.write(out, overwrite=True) == out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.npz"]  # no .part left behind


def test_python_m_runs_the_command() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "robot_retarget", "--version"],
        capture_output=True, text=True, check=True, cwd=REPO,
    )  # fmt: skip
    assert out.stdout.startswith("robot-retarget ")


def test_the_report_prints_as_convert_does_and_an_existing_file_is_an_output_error(
    tmp_path: Path,
) -> None:
    """``print(result.report)`` printed the whole dataclass, trajectory included; writing over
    a file without overwrite=True is an OutputWriteError (a MotionFormatError as before)."""
    from robot_retarget.errors import MotionFormatError, OutputWriteError

    result = rr.retarget(CLIP, robot="op3")
    text = str(result.report)
    assert text.startswith(f"{result.trajectory.num_frames} frames, ")
    assert "limits respected" in text
    assert "RobotTrajectory" not in text
    out = result.trajectory.write(tmp_path / "w.npz")
    with pytest.raises(OutputWriteError, match="already exists") as info:
        result.trajectory.write(out)
    assert isinstance(info.value, MotionFormatError)


def test_an_excess_within_the_tolerance_is_reported_as_none() -> None:
    """A step 3e-17 rad over v_max · dt (float rounding) was reported as that excess beside
    "limits respected"."""
    from robot_retarget.pipeline.convert import check_limits

    config = rr.load_robot("op3")
    mid = 0.5 * (config.lower + config.upper)
    q = np.vstack([mid, mid + config.max_velocity * 0.008 + 3e-17])
    check = check_limits(config, q, 0.008)
    assert check.ok
    assert (check.position_excess_rad, check.velocity_excess_rad) == (0.0, 0.0)
    q[1, 0] += 1e-6
    assert check_limits(config, q, 0.008).velocity_excess_rad == pytest.approx(1e-6, rel=1e-3)


def test_the_readmes_live_loop_runs_as_written() -> None:
    """The "Your own live loop" example, on a short clip: every command passes the safety
    layer unchanged."""
    import contextlib
    import io
    import re

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    code = next(b for b in re.findall(r"```python\n(.*?)```", readme, re.S) if "RetargetStep(" in b)
    clip = Path(__file__).parent / "fixtures" / "motion" / "tiny_walk.bvh"
    code = code.replace('"walk.bvh"', repr(str(clip)))
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, "README.md", "exec"), {})
    assert "safety: 0 of 24 commands clipped" in printed.getvalue()


def test_retarget_takes_a_lead_in_as_convert_does() -> None:
    """``lead_in=True``: the move from the init pose comes first, stamped before t = 0, at the
    ramp speed; the clip's own frames are those without it."""
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.pipeline.convert import LEAD_IN_SPEED_FRACTION

    motion = demo_motion(fps=30.0).frames(0, 15)
    plain = rr.retarget(motion, "op3", "copy")
    led = rr.retarget(motion, "op3", "copy", lead_in=True)
    config = rr.load_robot("op3")
    n = led.trajectory.num_frames - plain.trajectory.num_frames
    assert n > 5
    q = np.asarray(led.trajectory.q)
    moved = np.vstack([config.init_pose, q[: n + 1]])  # from the init pose
    steps = np.abs(np.diff(moved, axis=0)) / (config.max_velocity / config.control_rate_hz)
    assert steps.max() <= LEAD_IN_SPEED_FRACTION + 1e-6
    np.testing.assert_allclose(q[n:], plain.trajectory.q, atol=1e-9)
