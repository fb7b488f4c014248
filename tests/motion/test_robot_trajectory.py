"""RobotTrajectory files: CSV / JSON / NPZ round trips, overwrite protection, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robot_retarget.errors import MotionFormatError
from robot_retarget.motion.trajectory import RobotTrajectory

NAMES = ("r_sho_pitch", "l_sho_pitch", "head_pan")


def make(frames: int = 5, seed: int = 0, full: bool = True, fps: float = 50.0) -> RobotTrajectory:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(frames, len(NAMES)))
    if not full:
        return RobotTrajectory(NAMES, q, fps)
    quats = rng.normal(size=(frames, 4))
    return RobotTrajectory(
        NAMES,
        q,
        fps,
        root_pos=rng.normal(size=(frames, 3)),
        root_quat=quats / np.linalg.norm(quats, axis=1, keepdims=True),
        t0=1.25,
        frame_ms=rng.uniform(0.1, 3.0, size=frames),
    )


def assert_same(a: RobotTrajectory, b: RobotTrajectory) -> None:
    assert a.joint_names == b.joint_names
    np.testing.assert_array_equal(a.q, b.q)
    assert b.fps == pytest.approx(a.fps, rel=1e-9)
    assert b.t0 == pytest.approx(a.t0, abs=1e-12)
    for key in ("root_pos", "root_quat", "frame_ms"):
        x, y = getattr(a, key), getattr(b, key)
        assert (x is None) == (y is None), key
        if x is not None:
            np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("suffix", [".csv", ".json", ".npz"])
@pytest.mark.parametrize("full", [True, False])
def test_round_trip(tmp_path: Path, suffix: str, full: bool) -> None:
    traj = make(full=full)
    back = RobotTrajectory.read(traj.write(tmp_path / f"t{suffix}"))
    assert_same(traj, back)


@given(
    frames=st.integers(2, 30),
    fps=st.sampled_from([24.0, 30.0, 100.0, 125.0]),
    seed=st.integers(0, 1000),
    suffix=st.sampled_from([".csv", ".json", ".npz"]),
)
@settings(max_examples=30, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_round_trip_property(
    tmp_path: Path, frames: int, fps: float, seed: int, suffix: str
) -> None:
    traj = make(frames, seed, fps=fps)
    back = RobotTrajectory.read(traj.write(tmp_path / f"p{suffix}", overwrite=True))
    assert_same(traj, back)


def test_csv_header_and_units(tmp_path: Path) -> None:
    path = make(full=False).write(tmp_path / "t.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "time," + ",".join(NAMES)
    assert len(lines) == 6
    assert float(lines[2].split(",")[0]) == pytest.approx(1 / 50.0)


def test_refuses_to_overwrite(tmp_path: Path) -> None:
    traj = make()
    path = traj.write(tmp_path / "t.json")
    with pytest.raises(MotionFormatError, match="overwrite=True"):
        traj.write(path)
    traj.write(path, overwrite=True)


@pytest.mark.parametrize("suffix", [".csv", ".json", ".npz"])
def test_nan_refused_on_write(tmp_path: Path, suffix: str) -> None:
    q = make(full=False).q.copy()
    q[2, 1] = np.nan
    traj = RobotTrajectory(NAMES, q, 50.0)
    with pytest.raises(MotionFormatError, match=r"l_sho_pitch.*frame 2"):
        traj.write(tmp_path / f"n{suffix}")
    assert not (tmp_path / f"n{suffix}").exists()


def test_nan_refused_on_read(tmp_path: Path) -> None:
    csv_path = tmp_path / "n.csv"
    csv_path.write_text("time,a,b\n0,0.1,0.2\n0.02,nan,0.2\n")
    with pytest.raises(MotionFormatError) as info:
        RobotTrajectory.read(csv_path)
    assert info.value.line == 3
    json_path = tmp_path / "n.json"
    json_path.write_text('{"joint_names": ["a"], "fps": 10, "q": [[0.1], [NaN]]}')
    with pytest.raises(MotionFormatError, match="NaN"):
        RobotTrajectory.read(json_path)
    npz_path = tmp_path / "n.npz"
    np.savez(npz_path, joint_names=np.array(["a"]), q=np.array([[np.nan]]), fps=np.array(10.0))
    with pytest.raises(MotionFormatError, match="NaN"):
        RobotTrajectory.read(npz_path)


@pytest.mark.parametrize("suffix", [".csv", ".json", ".npz"])
def test_non_unit_root_quat_refused_on_write(tmp_path: Path, suffix: str) -> None:
    good = make()
    quats = good.root_quat.copy()
    quats[3] *= 2.0  # a scaled quaternion: not a rotation until normalised
    traj = RobotTrajectory(NAMES, good.q, 50.0, root_pos=good.root_pos, root_quat=quats)
    with pytest.raises(MotionFormatError, match=r"root_quat at frame 3 has norm 2 \(1 of 5"):
        traj.write(tmp_path / f"q{suffix}")
    assert not (tmp_path / f"q{suffix}").exists()


def test_non_unit_root_quat_refused_on_read(tmp_path: Path) -> None:
    header = "time,a,root_qw,root_qx,root_qy,root_qz\n"
    path = tmp_path / "q.csv"
    path.write_text(header + "0,0.1,1,0,0,0\n0.02,0.1,0,0,0,0\n")
    with pytest.raises(MotionFormatError, match=r"frame 1 has norm 0 .*unit quaternion w-x-y-z"):
        RobotTrajectory.read(path)
    # A float32 or few-decimal round trip is well inside the tolerance and read as written.
    path.write_text(header + "0,0.1,0.7071,0.7071,0,0\n0.02,0.1,0.99995,0,0,0\n")
    np.testing.assert_array_equal(RobotTrajectory.read(path).root_quat[:, 0], [0.7071, 0.99995])


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("", 1, "empty"),
        ("t,a\n0,1\n", 1, "'time'"),
        ("time,a,b\n0,1\n", 2, "columns"),
        ("time,a\n0,x\n", 2, "not a number"),
        ("time,a\n0,1\n0,2\n", 3, "increase"),
        ("time,a\n", 2, "no data"),
        ("time,a,root_qw\n0,1,1\n0.1,1,1\n", 1, "bad header"),
    ],
)
def test_malformed_csv(tmp_path: Path, text: str, line: int, words: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(MotionFormatError, match=words) as info:
        RobotTrajectory.read(path)
    assert info.value.line == line


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("{", "not valid JSON"),
        ("[1, 2]", "JSON object"),
        ('{"joint_names": ["a"], "q": [[0]]}', "missing keys"),
        ('{"joint_names": ["a"], "fps": 10, "q": [[0, 1]]}', "shape"),
        ('{"joint_names": [1], "fps": 10, "q": [[0]]}', "list of strings"),
        ('{"joint_names": ["a"], "fps": "fast", "q": [[0]]}', "numbers"),
    ],
)
def test_malformed_json(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(MotionFormatError, match=words):
        RobotTrajectory.read(path)


def test_malformed_npz(tmp_path: Path) -> None:
    path = tmp_path / "bad.npz"
    path.write_bytes(b"not a zip")
    with pytest.raises(MotionFormatError, match="npz"):
        RobotTrajectory.read(path)
    np.savez(path, q=np.zeros((2, 1)), fps=np.array(10.0))
    with pytest.raises(MotionFormatError, match="missing arrays"):
        RobotTrajectory.read(path)


def test_unsupported_suffix_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MotionFormatError, match="unsupported"):
        make().write(tmp_path / "t.txt")
    with pytest.raises(MotionFormatError, match="cannot read"):
        RobotTrajectory.read(tmp_path / "absent.csv")
    # what view and inspect are given by mistake: each named for what it is
    with pytest.raises(MotionFormatError, match="a folder, not a trajectory file"):
        RobotTrajectory.read(tmp_path)  # it said "unsupported trajectory file type '(none)'"
    with pytest.raises(MotionFormatError, match=r"a BVH motion clip.*convert it first"):
        RobotTrajectory.read(tmp_path / "walk.bvh")


def test_constructor_validation_and_times() -> None:
    traj = make(4, full=False, fps=20.0)
    np.testing.assert_allclose(traj.times_s(), [0.0, 0.05, 0.1, 0.15])
    assert traj.duration_s == pytest.approx(0.2)
    with pytest.raises(ValueError, match="shape"):
        RobotTrajectory(NAMES, np.zeros((3, 2)), 10.0)
    with pytest.raises(ValueError, match="unique"):
        RobotTrajectory(("a", "a"), np.zeros((3, 2)), 10.0)
    with pytest.raises(ValueError, match="root_pos"):
        RobotTrajectory(("a",), np.zeros((3, 1)), 10.0, root_pos=np.zeros((2, 3)))


def test_reserved_csv_names_are_refused(tmp_path: Path) -> None:
    traj = RobotTrajectory(("time",), np.zeros((2, 1)), 10.0)
    with pytest.raises(MotionFormatError, match="reserved"):
        traj.write(tmp_path / "r.csv")
