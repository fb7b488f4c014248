"""BVH reader and writer: syntax variants, channel orders, malformed files, round trips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from robot_retarget.errors import MotionFormatError
from robot_retarget.motion.bvh import BvhClip, format_bvh, parse_bvh, read_bvh, write_bvh

# file → the 1-based line its error must name (see tests/fixtures/motion/generate.py)
MALFORMED = {
    "truncated.bvh": 21,
    "wrong_channel_count.bvh": 20,
    "non_numeric.bvh": 21,
    "missing_motion.bvh": 16,
    "zero_frames.bvh": 17,
    "nan_value.bvh": 20,
    "inf_value.bvh": 19,
    "duplicate_joint.bvh": 6,
    "unknown_channel.bvh": 9,
    "bad_channels_count.bvh": 9,
    "missing_open_brace.bvh": 7,
    "missing_close_brace.bvh": 15,
    "negative_frame_time.bvh": 18,
    "zero_frame_time.bvh": 18,
    "not_bvh.bvh": 1,
    "bad_offset.bvh": 8,
}

# A word in each message, so every case fails for its own reason.
MALFORMED_WORDS = {
    "truncated.bvh": "truncated",
    "wrong_channel_count.bvh": "channels",
    "non_numeric.bvh": "not a number",
    "missing_motion.bvh": "MOTION",
    "zero_frames.bvh": "at least one frame",
    "nan_value.bvh": "NaN",
    "inf_value.bvh": "infinity",
    "duplicate_joint.bvh": "duplicate",
    "unknown_channel.bvh": "unknown channel",
    "bad_channels_count.bvh": "count",
    "missing_open_brace.bvh": "'{'",
    "missing_close_brace.bvh": "'}'",
    "negative_frame_time.bvh": "positive",
    "zero_frame_time.bvh": "positive",
    "not_bvh.bvh": "HIERARCHY",
    "bad_offset.bvh": "OFFSET",
}

SMALL = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Zrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.5
1 2 3 0 0 0 90 0 0
1 2 3 90 0 0 0 0 0
"""


def reference_positions(clip: BvhClip) -> np.ndarray:
    """Global joint positions with scipy, straight from the raw channels (independent FK)."""
    t = clip.num_frames
    pos = np.zeros((t, clip.num_joints, 3))
    rots: list[Rotation] = []
    for j, chans in enumerate(clip.channels):
        cols = clip.motion[:, clip.channel_start[j] : clip.channel_start[j] + len(chans)]
        rot_cols = [k for k, c in enumerate(chans) if c.endswith("rotation")]
        order = "".join(chans[k][0] for k in rot_cols)
        local = (
            Rotation.from_euler(order, cols[:, rot_cols], degrees=True)
            if rot_cols
            else Rotation.identity(t)
        )
        trans = np.tile(clip.offsets[j], (t, 1))
        for k, c in enumerate(chans):
            if c.endswith("position"):
                trans[:, "XYZ".index(c[0])] = cols[:, k]
        p = clip.parents[j]
        if p < 0:
            pos[:, j] = trans
            rots.append(local)
        else:
            pos[:, j] = pos[:, p] + rots[p].apply(trans)
            rots.append(rots[p] * local)
    return pos


def test_parses_small_clip_exactly() -> None:
    clip = parse_bvh(SMALL)
    assert clip.names == ("Hips", "Chest")
    assert clip.parents == (-1, 0)
    assert clip.channels[1] == ("Xrotation", "Zrotation", "Yrotation")
    assert clip.end_site_parents == (1,)
    np.testing.assert_allclose(clip.end_site_offsets, [[0, 5, 0]])
    assert clip.frame_time_s == 0.5
    assert clip.fps == 2.0
    pos = clip.global_positions()
    # Frame 0: Chest rotated 90° about its X axis; its End Site (0, 5, 0) goes to (0, 0, 5).
    np.testing.assert_allclose(pos[0, 1], [1, 12, 3], atol=1e-12)
    np.testing.assert_allclose(clip.end_site_positions()[0, 0], [1, 12, 8], atol=1e-12)
    # Frame 1: Hips turned 90° about Z; the chest offset (0, 10, 0) turns to (-10, 0, 0).
    np.testing.assert_allclose(pos[1, 1], [1 - 10, 2, 3], atol=1e-12)


@pytest.mark.parametrize(
    "name",
    [
        "tiny_walk.bvh",
        "asf_names.bvh",
        "unknown_names.bvh",
        "mixamo.bvh",
        "crlf_tabs.bvh",
        "z_up.bvh",
    ],
)
def test_fixture_positions_match_scipy(motion_fixtures: Path, name: str) -> None:
    clip = read_bvh(motion_fixtures / name)
    np.testing.assert_allclose(clip.global_positions(), reference_positions(clip), atol=1e-9)


def test_crlf_tabs_and_non_root_position_channels(motion_fixtures: Path) -> None:
    raw = (motion_fixtures / "crlf_tabs.bvh").read_bytes()
    assert b"\r\n" in raw
    assert b"\t" in raw
    clip = read_bvh(motion_fixtures / "crlf_tabs.bvh")
    collar = clip.names.index("lCollar")
    assert clip.channels[collar][:3] == ("Xposition", "Yposition", "Zposition")
    trans = clip.local_translations()[:, collar]
    # The collar's position channels move it up and down around its OFFSET.
    assert np.ptp(trans[:, 1]) > 1.0
    np.testing.assert_allclose(trans[:, 0], clip.offsets[collar, 0])


@pytest.mark.parametrize("name", sorted(MALFORMED))
def test_malformed_files_name_the_line(motion_fixtures: Path, name: str) -> None:
    path = motion_fixtures / "malformed" / name
    with pytest.raises(MotionFormatError) as info:
        read_bvh(path)
    assert info.value.line == MALFORMED[name]
    assert info.value.path == str(path)
    assert MALFORMED_WORDS[name] in str(info.value)


def test_missing_file_is_a_motion_format_error(tmp_path: Path) -> None:
    with pytest.raises(MotionFormatError, match="cannot read"):
        read_bvh(tmp_path / "nope.bvh")


def test_extra_rows_are_refused() -> None:
    with pytest.raises(MotionFormatError) as info:
        parse_bvh(SMALL + "1 2 3 0 0 0 0 0 0\n")
    assert info.value.line == 21  # SMALL has 20 lines


def test_arbitrary_whitespace_and_blank_lines() -> None:
    messy = "\n\n" + SMALL.replace("  ", "\t \t").replace("\n1 2 3", "\n\n   1  2\t3")
    a = parse_bvh(SMALL)
    b = parse_bvh(messy)
    np.testing.assert_array_equal(a.motion, b.motion)
    assert a.names == b.names
    assert a.channels == b.channels


def test_max_frames_reads_only_the_start() -> None:
    clip = parse_bvh(SMALL, max_frames=1)
    assert clip.num_frames == 1
    # Rows after max_frames are not even looked at: a broken tail does not matter.
    assert parse_bvh(SMALL + "garbage\n", max_frames=1).num_frames == 1
    # ... but a file cut short is refused whatever max_frames reads of it (it was taken).
    cut = SMALL.rsplit("\n", 2)[0] + "\n"  # Frames: 2, one row
    with pytest.raises(MotionFormatError, match="only 1 motion row; the file is truncated"):
        parse_bvh(cut, max_frames=1)


@given(
    order=st.permutations(["X", "Y", "Z"]),
    angles=st.lists(st.floats(-179.0, 179.0), min_size=3, max_size=3),
)
@settings(max_examples=40)
def test_any_rotation_order_composes_in_listed_order(order: list[str], angles: list[float]) -> None:
    chans = " ".join(f"{a}rotation" for a in order)
    text = SMALL.replace("Xrotation Zrotation Yrotation", chans).replace(
        "1 2 3 0 0 0 90 0 0", "1 2 3 0 0 0 " + " ".join(repr(a) for a in angles)
    )
    clip = parse_bvh(text)
    expected = Rotation.from_euler("".join(order), angles, degrees=True).as_quat()  # x y z w
    got = clip.local_rotations()[0, 1]
    dot = abs(float(np.dot(got, np.roll(expected, 1))))
    assert dot == pytest.approx(1.0, abs=1e-12)


def test_reads_a_long_real_clip(mocap_dir: Path) -> None:
    clip = read_bvh(mocap_dir / "02" / "02_10.bvh")
    assert clip.num_frames == 2646
    assert np.isfinite(clip.local_rotations()).all()


@pytest.mark.parametrize(
    "name", ["tiny_walk.bvh", "asf_names.bvh", "unknown_names.bvh", "mixamo.bvh", "crlf_tabs.bvh"]
)
def test_write_read_round_trip_fixtures(motion_fixtures: Path, tmp_path: Path, name: str) -> None:
    clip = read_bvh(motion_fixtures / name)
    out = write_bvh(tmp_path / name, clip)
    back = read_bvh(out)
    assert back.names == clip.names
    assert back.channels == clip.channels
    a = clip.global_positions()
    b = back.global_positions()
    assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(a))


def test_write_read_round_trip_real_clip(mocap_dir: Path, tmp_path: Path) -> None:
    clip = read_bvh(mocap_dir / "13" / "13_11.bvh", max_frames=150)
    back = read_bvh(write_bvh(tmp_path / "c.bvh", clip))
    a = clip.global_positions()
    np.testing.assert_allclose(back.global_positions(), a, rtol=0, atol=1e-6 * np.max(np.abs(a)))
    np.testing.assert_allclose(back.end_site_positions(), clip.end_site_positions(), atol=1e-6)


def test_writer_refuses_to_overwrite(tmp_path: Path) -> None:
    clip = parse_bvh(SMALL)
    path = write_bvh(tmp_path / "a.bvh", clip)
    with pytest.raises(MotionFormatError, match="overwrite=True"):
        write_bvh(path, clip)
    write_bvh(path, clip, overwrite=True)
    assert read_bvh(path).num_frames == 2


def test_format_bvh_is_parseable_text() -> None:
    clip = parse_bvh(SMALL)
    text = format_bvh(clip)
    assert text.startswith("HIERARCHY\nROOT Hips\n")
    assert "Frames: 2" in text
    np.testing.assert_array_equal(parse_bvh(text).motion, clip.motion)


def test_clip_rejects_inconsistent_arrays() -> None:
    clip = parse_bvh(SMALL)
    with pytest.raises(ValueError, match="motion must have shape"):
        BvhClip(
            clip.names,
            clip.parents,
            clip.offsets,
            clip.channels,
            clip.end_site_parents,
            clip.end_site_offsets,
            clip.frame_time_s,
            clip.motion[:, :5],
        )


@pytest.mark.parametrize("axes", ["Y", "XZ", "ZY"])
def test_fewer_than_three_rotation_channels(axes: str) -> None:
    chans = " ".join(f"{a}rotation" for a in axes)
    angles = [10.0, -35.0, 70.0, 5.0][: len(axes)]
    text = (
        SMALL.replace("CHANNELS 3 Xrotation Zrotation Yrotation", f"CHANNELS {len(axes)} {chans}")
        .replace("1 2 3 0 0 0 90 0 0", "1 2 3 0 0 0 " + " ".join(map(str, angles)))
        .replace("1 2 3 90 0 0 0 0 0", "1 2 3 0 0 0 " + " ".join(["0"] * len(axes)))
    )
    clip = parse_bvh(text)
    expected = Rotation.identity()
    for a, v in zip(axes, angles, strict=True):
        expected = expected * Rotation.from_euler(a, v, degrees=True)
    got = clip.local_rotations()[0, 1]
    assert abs(float(np.dot(got, np.roll(expected.as_quat(), 1)))) == pytest.approx(1.0)


def test_repeated_channel_is_refused() -> None:
    text = SMALL.replace("Xrotation Zrotation Yrotation", "Zrotation Xrotation Zrotation")
    with pytest.raises(MotionFormatError, match="listed twice") as info:
        parse_bvh(text)
    assert info.value.line == 9
