"""HumanMotion: validation, FK, resampling, BVH export round trip, load_motion options."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.errors import MotionFormatError
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import read_bvh, write_bvh
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.skeleton import Skeleton, default_canonical_skeleton


def random_motion(frames: int, seed: int, fps: float = 30.0) -> HumanMotion:
    rng = np.random.default_rng(seed)
    q = quat.from_rotation_vector(rng.normal(scale=0.6, size=(frames, 22, 3)))
    root = rng.normal(size=(frames, 3))
    return HumanMotion(default_canonical_skeleton(), q, root, fps)


def test_constructor_normalises_and_makes_continuous() -> None:
    m = random_motion(5, 1)
    flipped = m.local_quats.copy()
    flipped[2] *= -1.0
    again = HumanMotion(m.skeleton, flipped, m.root_pos, m.fps)
    assert np.all(np.sum(again.local_quats[1:] * again.local_quats[:-1], axis=-1) >= 0.0)
    np.testing.assert_allclose(again.positions(), m.positions(), atol=1e-12)
    assert not again.local_quats.flags.writeable


def test_constructor_rejects_bad_input() -> None:
    m = random_motion(3, 2)
    with pytest.raises(ValueError, match="unit quaternions"):
        HumanMotion(m.skeleton, m.local_quats * 2.0, m.root_pos, 30.0)
    with pytest.raises(ValueError, match="root_pos"):
        HumanMotion(m.skeleton, m.local_quats, m.root_pos[:2], 30.0)
    bad = m.local_quats.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        HumanMotion(m.skeleton, bad, m.root_pos, 30.0)
    with pytest.raises(ValueError, match="fps"):
        HumanMotion(m.skeleton, m.local_quats, m.root_pos, 0.0)
    with pytest.raises(ValueError, match="canonical"):
        HumanMotion(Skeleton(("a",), (-1,), np.zeros((1, 3))), m.local_quats, m.root_pos, 30.0)


def test_sizes_and_default_height() -> None:
    m = random_motion(12, 3, fps=24.0)
    assert m.num_frames == 12
    assert m.duration_s == pytest.approx(0.5)
    assert m.height_m == pytest.approx(1.6, abs=0.1)  # default skeleton, Head joint as top
    assert m.synthesized_joints == ()
    assert not m.dropped_tpose


def test_positions_root_follows_root_pos() -> None:
    m = random_motion(4, 4)
    np.testing.assert_allclose(m.positions()[:, 0], m.root_pos)
    assert m.global_quats().shape == (4, 22, 4)


def test_frames_slices() -> None:
    m = random_motion(10, 5)
    part = m.frames(2, 5)
    assert part.num_frames == 3
    np.testing.assert_array_equal(part.root_pos, m.root_pos[2:5])
    with pytest.raises(ValueError, match="no frame"):
        m.frames(20)


@given(
    src_fps=st.sampled_from([24.0, 30.0, 60.0, 120.0]),
    dst_fps=st.sampled_from([10.0, 25.0, 30.0, 50.0]),
)
@settings(max_examples=12)
def test_resample_keeps_span_and_endpoints(src_fps: float, dst_fps: float) -> None:
    m = random_motion(13, 6, fps=src_fps)
    r = m.resample(dst_fps)
    assert r.fps == dst_fps
    span = (m.num_frames - 1) / src_fps
    assert (r.num_frames - 1) / dst_fps <= span + 1e-9
    assert r.num_frames == int(np.floor(span * dst_fps + 1e-9)) + 1
    np.testing.assert_allclose(r.root_pos[0], m.root_pos[0])
    assert np.allclose(quat.angle_between(r.local_quats[0], m.local_quats[0]), 0.0, atol=1e-7)


def test_resample_to_same_rate_is_identity_and_halfway_is_slerp() -> None:
    m = random_motion(6, 7, fps=30.0)
    same = m.resample(30.0)
    np.testing.assert_allclose(same.positions(), m.positions(), atol=1e-9)
    double = m.resample(60.0)
    assert double.num_frames == 11
    mid = quat.slerp(m.local_quats[0], m.local_quats[1], 0.5)
    assert np.allclose(quat.angle_between(double.local_quats[1], mid), 0.0, atol=1e-7)
    np.testing.assert_allclose(double.root_pos[1], 0.5 * (m.root_pos[0] + m.root_pos[1]))


@pytest.mark.parametrize(
    ("root", "joint", "unit"),
    [
        (None, None, "m"),
        (("Zposition", "Xposition", "Yposition", "Xrotation", "Yrotation", "Zrotation"),
         ("Yrotation", "Zrotation", "Xrotation"), "cm"),
    ],
)  # fmt: skip
def test_bvh_export_round_trip(
    tmp_path: Path, root: tuple[str, ...] | None, joint: tuple[str, ...] | None, unit: str
) -> None:
    m = random_motion(8, 8)
    kwargs = {} if root is None else {"root_channels": root, "joint_channels": joint}
    path = write_bvh(tmp_path / "m.bvh", m, unit=unit, **kwargs)  # type: ignore[arg-type]
    back = load_motion(path, drop_tpose=False)
    assert back.unit == unit
    assert back.name_family == "Mixamo"
    a = m.positions() - m.root_pos[:, None]
    b = back.positions() - back.root_pos[:, None]
    assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(a))
    np.testing.assert_allclose(back.root_pos, m.root_pos, rtol=1e-6, atol=1e-9)
    if root is not None:
        assert read_bvh(path).channels[0] == root


def test_real_clip_export_round_trip(mocap_dir: Path, tmp_path: Path) -> None:
    m = load_motion(mocap_dir / "07" / "07_01.bvh", max_frames=100)
    back = load_motion(write_bvh(tmp_path / "c.bvh", m, unit="cm"), drop_tpose=False)
    a = m.positions()
    assert np.max(np.abs(back.positions() - a)) <= 1e-6 * np.max(np.abs(a))


def test_export_rejects_bad_channels() -> None:
    with pytest.raises(MotionFormatError, match="three different"):
        random_motion(2, 9).to_bvh_clip(joint_channels=("Zrotation", "Zrotation", "Xrotation"))


def test_load_motion_options(motion_fixtures: Path) -> None:
    path = motion_fixtures / "tiny_walk.bvh"
    m = load_motion(path, max_frames=5)
    assert m.num_frames == 5
    assert m.tpose_frames_dropped == 1
    assert load_motion(path, drop_tpose=False).num_frames == 25
    assert load_motion(path, drop_tpose=True).num_frames == 24
    with pytest.raises(MotionFormatError, match=r"not a motion clip \(\.py\)"):
        load_motion(motion_fixtures / "generate.py")
    with pytest.raises(MotionFormatError, match="unknown length unit"):
        load_motion(path, unit="furlong")
    with pytest.raises(MotionFormatError, match="unknown up axis"):
        load_motion(path, up_axis="w")


def test_replace_keeps_validation() -> None:
    m = random_motion(3, 10)
    with pytest.raises(ValueError, match="fps"):
        dataclasses.replace(m, fps=-1.0)
