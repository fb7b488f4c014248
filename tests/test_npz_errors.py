"""A file that is not an .npz archive: a plain error, never numpy's advice to unpickle it."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_retarget.errors import ModelLoadError, MotionFormatError
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.runtime.npz_file import read_runtime_npz


@pytest.mark.parametrize("content", [b"hello\n", b"PK\x03\x04cut"])
def test_a_file_that_is_no_archive_is_named_so(tmp_path: Path, content: bytes) -> None:
    fake = tmp_path / "fake.npz"
    fake.write_bytes(content)
    with pytest.raises(MotionFormatError, match=r"not an \.npz") as traj:
        RobotTrajectory.read(fake)
    with pytest.raises(ModelLoadError, match=r"not an \.npz") as model:
        read_runtime_npz(fake, "runtime file")
    for exc in (traj.value, model.value):
        assert "pickle" not in str(exc)


def test_a_trajectory_given_as_motion_says_what_reads_it(tmp_path: Path) -> None:
    with pytest.raises(MotionFormatError, match=r"not a motion clip \(\.npz\).*`view` shows it"):
        load_motion(tmp_path / "walk_op3.npz")
