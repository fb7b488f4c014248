"""Canonicalisation of real and hand-made clips: families, units, exact positions, Z-up."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot_retarget.errors import MotionFormatError
from robot_retarget.motion import name_families as nf
from robot_retarget.motion.bvh import BvhClip, read_bvh
from robot_retarget.motion.canonicalize import canonicalize, detect_up_axis
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.motion.joint_map import JointMap
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS

EXACT = (
    "LeftHand", "RightHand", "LeftForeArm", "RightForeArm", "LeftArm", "RightArm",
    "LeftFoot", "RightFoot", "LeftLeg", "RightLeg", "LeftToeBase", "RightToeBase",
    "LeftUpLeg", "RightUpLeg", "Spine2",
)  # fmt: skip


def scipy_positions(clip: BvhClip) -> np.ndarray:
    """Source global joint positions from the raw channels with scipy (independent FK)."""
    t = clip.num_frames
    pos = np.zeros((t, clip.num_joints, 3))
    rots: list[Rotation] = []
    for j, chans in enumerate(clip.channels):
        cols = clip.motion[:, clip.channel_start[j] : clip.channel_start[j] + len(chans)]
        rk = [k for k, c in enumerate(chans) if c.endswith("rotation")]
        local = Rotation.from_euler("".join(chans[k][0] for k in rk), cols[:, rk], degrees=True)
        trans = np.tile(clip.offsets[j], (t, 1))
        for k, c in enumerate(chans):
            if c.endswith("position"):
                trans[:, "XYZ".index(c[0])] = cols[:, k]
        p = clip.parents[j]
        pos[:, j] = trans if p < 0 else pos[:, p] + rots[p].apply(trans)
        rots.append(local if p < 0 else rots[p] * local)
    return pos


def bone_lengths(motion: HumanMotion) -> np.ndarray:
    pos = motion.positions()
    parents = np.array(CANONICAL_PARENTS[1:])
    return np.linalg.norm(pos[:, 1:] - pos[:, parents], axis=-1)  # (T, 21)


def assert_constant_bones(motion: HumanMotion) -> None:
    lengths = bone_lengths(motion)
    rest = np.linalg.norm(motion.skeleton.offsets[1:], axis=-1)
    scale = max(float(np.max(rest)), 1e-12)
    np.testing.assert_allclose(lengths, np.broadcast_to(rest, lengths.shape), atol=1e-9 * scale)


def test_all_clips_load_map_and_keep_bone_lengths(mocap_clips: list[Path]) -> None:
    assert len(mocap_clips) == 70
    for path in mocap_clips:
        motion = load_motion(path, max_frames=200)
        daz = int(path.parent.name) >= 10
        assert motion.name_family == (nf.DAZ if daz else nf.CMU_MOTIONBUILDER), path
        assert motion.skeleton.names == CANONICAL_JOINTS
        assert motion.unit == ("cm" if daz else "cmu"), path
        assert 1.4 <= motion.height_m <= 2.0, (path, motion.height_m)
        assert motion.fps == pytest.approx(120.0, rel=1e-4)
        assert motion.dropped_tpose == (not daz), path
        assert motion.num_frames == min(
            200, read_bvh(path).num_frames - motion.tpose_frames_dropped
        )
        assert motion.up_axis == "y"
        assert_constant_bones(motion)
        q = motion.local_quats
        np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
        assert np.all(np.sum(q[1:] * q[:-1], axis=-1) >= 0.0)  # sign-continuous


@pytest.mark.parametrize("clip", ["02/02_10.bvh", "05/05_02.bvh", "14/14_08.bvh"])
def test_bone_lengths_constant_over_whole_long_clips(mocap_dir: Path, clip: str) -> None:
    motion = load_motion(mocap_dir / clip)
    assert motion.num_frames > 1000
    assert_constant_bones(motion)


def test_mb2_canonical_positions_equal_source_positions(mocap_clips: list[Path]) -> None:
    mb2 = [p for p in mocap_clips if int(p.parent.name) < 10]
    assert len(mb2) == 56
    for path in mb2:
        clip = read_bvh(path, max_frames=120)
        motion = canonicalize(clip, drop_tpose=False)
        scale = 100.0 / 0.45 * 0.0254 / 100.0  # metres per CMU unit
        src = scipy_positions(clip) * scale
        got = motion.positions()
        for name in EXACT:
            source_name = "Spine1" if name == "Spine2" else name
            s = clip.names.index(source_name)
            c = CANONICAL_JOINTS.index(name)
            np.testing.assert_allclose(got[:, c], src[:, s], atol=1e-9, err_msg=f"{path} {name}")


def test_daz_limbs_and_synthesised_toes_land_on_source_points(mocap_dir: Path) -> None:
    clip = read_bvh(mocap_dir / "12" / "12_01.bvh", max_frames=60)
    motion = canonicalize(clip)
    assert motion.synthesized_joints == ("Spine1", "LeftToeBase", "RightToeBase")
    src = clip.global_positions() * 0.01
    ends = clip.end_site_positions() * 0.01
    got = motion.positions()
    for canon, source in [("LeftHand", "lHand"), ("RightFoot", "rFoot"), ("LeftLeg", "lShin")]:
        np.testing.assert_allclose(
            got[:, CANONICAL_JOINTS.index(canon)], src[:, clip.names.index(source)], atol=1e-9
        )
    # The synthesised toe sits on the foot's End Site.
    foot_end = clip.end_site_parents.index(clip.names.index("lFoot"))
    np.testing.assert_allclose(
        got[:, CANONICAL_JOINTS.index("LeftToeBase")], ends[:, foot_end], atol=1e-9
    )


def test_tpose_kept_when_asked(mocap_dir: Path) -> None:
    kept = load_motion(mocap_dir / "02" / "02_01.bvh", drop_tpose=False, max_frames=20)
    dropped = load_motion(mocap_dir / "02" / "02_01.bvh", max_frames=20)
    assert not kept.dropped_tpose
    assert dropped.tpose_frames_dropped == 1
    np.testing.assert_allclose(kept.local_quats[1:], dropped.local_quats[:19], atol=1e-12)


def test_unit_override_scales_everything(motion_fixtures: Path) -> None:
    auto = load_motion(motion_fixtures / "mixamo.bvh")
    assert auto.unit == "cm"
    forced = load_motion(motion_fixtures / "mixamo.bvh", unit="m")
    assert forced.unit == "m"
    assert forced.height_m == pytest.approx(100.0 * auto.height_m)
    np.testing.assert_allclose(forced.root_pos, 100.0 * auto.root_pos)


def test_z_up_file_becomes_y_up(motion_fixtures: Path) -> None:
    ref = load_motion(motion_fixtures / "y_up_reference.bvh")
    zup = load_motion(motion_fixtures / "z_up.bvh")
    assert ref.up_axis == "y"
    assert zup.up_axis == "z"
    np.testing.assert_allclose(zup.positions(), ref.positions(), atol=1e-6)
    np.testing.assert_allclose(zup.skeleton.offsets, ref.skeleton.offsets, atol=1e-6)
    # Forcing the wrong up axis gives a visibly different (lying) skeleton.
    lying = load_motion(motion_fixtures / "z_up.bvh", up_axis="y")
    assert not np.allclose(lying.positions(), ref.positions(), atol=1e-2)


@pytest.mark.parametrize(
    ("name", "family", "unit"),
    [
        ("tiny_walk.bvh", nf.CMU_MOTIONBUILDER, "cmu"),
        ("asf_names.bvh", nf.CMU_ASF, "cmu"),
        ("unknown_names.bvh", nf.AUTOMATIC, "m"),
        ("mixamo.bvh", nf.MIXAMO, "cm"),
        ("crlf_tabs.bvh", nf.DAZ, "cm"),
    ],
)
def test_fixtures_canonicalise(motion_fixtures: Path, name: str, family: str, unit: str) -> None:
    motion = load_motion(motion_fixtures / name)
    assert motion.name_family == family
    assert motion.unit == unit
    assert motion.height_m == pytest.approx(1.7, abs=0.12)
    assert_constant_bones(motion)
    # The hand-made person walks along +Z with the left side at +X.
    pos = motion.positions()
    left = pos[:, CANONICAL_JOINTS.index("LeftUpLeg"), 0]
    right = pos[:, CANONICAL_JOINTS.index("RightUpLeg"), 0]
    assert np.all(left > right)
    assert motion.root_pos[-1, 2] > motion.root_pos[0, 2]


def test_fixture_walks_agree_across_families(motion_fixtures: Path) -> None:
    """The same person under four naming families gives the same canonical limb motion."""
    ref = load_motion(motion_fixtures / "y_up_reference.bvh").positions()
    limbs = [CANONICAL_JOINTS.index(n) for n in ("LeftHand", "RightFoot", "LeftLeg", "Head")]
    for name in ("asf_names.bvh", "unknown_names.bvh", "mixamo.bvh"):
        got = load_motion(motion_fixtures / name).positions()
        np.testing.assert_allclose(got[:12, limbs], ref[:, limbs], atol=2e-4, err_msg=name)


def test_ambiguous_up_axis_asks_for_it() -> None:
    points = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    where = {"Head": 0, "LeftFoot": 1, "RightFoot": 2}
    jm = JointMap(
        family="test",
        source_joints=(None,) * len(CANONICAL_JOINTS),
        rotation_joints=(0,) * len(CANONICAL_JOINTS),
        position_points=tuple(where.get(n, 0) for n in CANONICAL_JOINTS),
        num_source_joints=3,
    )
    with pytest.raises(MotionFormatError, match="pass up_axis"):
        detect_up_axis(points, jm)
    assert detect_up_axis(points * [0.1, 1.0, 0.1], jm) == "y"
    assert detect_up_axis(points * [0.1, 0.1, -1.0], jm) == "-z"


def test_max_frames_must_be_positive(motion_fixtures: Path) -> None:
    with pytest.raises(ValueError, match="at least 1"):
        load_motion(motion_fixtures / "tiny_walk.bvh", max_frames=0)


def test_cmu_clip_is_expressed_relative_to_the_tpose(shared_data_dir: Path) -> None:
    """The CMU conversion's rest thighs splay 20°: after canonicalisation the rest legs point
    straight down, so rotations copied onto a straight-legged robot do not cross its legs."""
    motion = load_motion(shared_data_dir / "mocap" / "02" / "02_01.bvh", max_frames=5)
    for joint in ("LeftLeg", "RightLeg", "LeftFoot", "RightFoot"):
        offset = motion.skeleton.offsets[motion.skeleton.index(joint)]
        np.testing.assert_allclose(offset / np.linalg.norm(offset), [0.0, -1.0, 0.0], atol=1e-12)
