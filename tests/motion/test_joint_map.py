"""Joint maps: family choice, synthesis of optional joints, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import JointMappingError
from robot_retarget.motion import name_families as nf
from robot_retarget.motion.auto_map import TreeGeometry
from robot_retarget.motion.bvh import read_bvh
from robot_retarget.motion.canonicalize import clip_geometry
from robot_retarget.motion.joint_map import FAMILIES, map_joints
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, Joint


@pytest.mark.parametrize(
    ("name", "family"),
    [
        ("tiny_walk.bvh", nf.CMU_MOTIONBUILDER),
        ("asf_names.bvh", nf.CMU_ASF),
        ("mixamo.bvh", nf.MIXAMO),
        ("crlf_tabs.bvh", nf.DAZ),
        ("unknown_names.bvh", nf.AUTOMATIC),
    ],
)
def test_family_detection(motion_fixtures: Path, name: str, family: str) -> None:
    clip = read_bvh(motion_fixtures / name, max_frames=1)
    jm = map_joints(clip.names, clip_geometry(clip))
    assert jm.family == family
    assert jm.synthesized == ()
    assert len(set(jm.source_joints)) == len(CANONICAL_JOINTS)


def test_daz_synthesis_rules(mocap_dir: Path) -> None:
    clip = read_bvh(mocap_dir / "10" / "10_04.bvh", max_frames=1)
    jm = map_joints(clip.names, clip_geometry(clip))
    assert jm.synthesized == ("Spine1", "LeftToeBase", "RightToeBase")
    # Spine1 copies Spine (same rotation source and position).
    assert jm.rotation_joints[Joint.Spine1] == jm.rotation_joints[Joint.Spine]
    assert jm.position_points[Joint.Spine1] == jm.position_points[Joint.Spine]
    # ToeBase rotates with the foot and sits on the foot's End Site.
    foot = clip.names.index("lFoot")
    assert jm.rotation_joints[Joint.LeftToeBase] == foot
    end = jm.position_points[Joint.LeftToeBase] - clip.num_joints
    assert clip.end_site_parents[end] == foot


def test_missing_shoulder_is_spine2_copy_at_the_arm(motion_fixtures: Path) -> None:
    clip = read_bvh(motion_fixtures / "mixamo.bvh", max_frames=1)
    names = tuple(n.replace("Shoulder", "Clavicle") for n in clip.names)
    jm = map_joints(names, clip_geometry(clip), family=nf.MIXAMO)
    assert "LeftShoulder" in jm.synthesized
    assert jm.rotation_joints[Joint.LeftShoulder] == jm.rotation_joints[Joint.Spine2]
    assert jm.position_points[Joint.LeftShoulder] == jm.position_points[Joint.LeftArm]


def test_forced_family_and_unknown_family(motion_fixtures: Path) -> None:
    clip = read_bvh(motion_fixtures / "tiny_walk.bvh", max_frames=1)
    geo = clip_geometry(clip)
    assert map_joints(clip.names, geo, family=nf.AUTOMATIC).family == nf.AUTOMATIC
    with pytest.raises(JointMappingError, match="unknown naming family"):
        map_joints(clip.names, geo, family="Blender")
    assert nf.AUTOMATIC in FAMILIES


def test_unmappable_skeleton_lists_missing_joints() -> None:
    # A lone arm: a chain of four joints, no legs, no spine branch.
    geo = TreeGeometry(
        (-1, 0, 1, 2),
        np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0.0]]),
        (3,),
        np.array([[4, 0, 0.0]]),
    )
    with pytest.raises(JointMappingError) as info:
        map_joints(("a", "b", "c", "d"), geo, path="arm.bvh")
    assert "Hips" in info.value.missing
    assert "LeftFoot" in info.value.missing
    assert "Hips" in str(info.value)
    assert info.value.path == "arm.bvh"


def test_family_names_in_wrong_places_are_not_trusted(motion_fixtures: Path) -> None:
    """Swapping two names so the tree contradicts them falls back to the geometry."""
    clip = read_bvh(motion_fixtures / "asf_names.bvh", max_frames=1)
    names = list(clip.names)
    a, b = names.index("lwrist"), names.index("head")
    names[a], names[b] = names[b], names[a]
    jm = map_joints(names, clip_geometry(clip))
    assert jm.family == nf.AUTOMATIC
    assert jm.source_names(names)["Head"] == "lwrist"
    assert jm.source_names(names)["LeftHand"] == "head"


@pytest.mark.parametrize(
    ("cut", "shifted"),
    [("LeftHand", "LeftHand on LeftForeArm"), ("LeftFoot", "LeftFoot on LeftToeBase")],
)
def test_a_named_skeleton_missing_a_joint_is_refused_not_shifted(
    mocap_dir: Path, cut: str, shifted: str
) -> None:
    """A CMU clip with one required joint cut out (its children re-parented, as an exporter
    that drops a joint does): the tree's rules would map a chain one joint off, so the error
    names the missing joint and what the layout would have done."""
    clip = read_bvh(mocap_dir / "02" / "02_01.bvh", max_frames=1)
    geo = clip_geometry(clip)
    j = clip.names.index(cut)
    keep = [k for k in range(clip.num_joints) if k != j]

    def reparented(p: int) -> int:
        p = geo.parents[j] if p == j else p
        return -1 if p < 0 else keep.index(p)

    parents = tuple(reparented(geo.parents[k]) for k in keep)
    sites = tuple(reparented(p) for p in geo.end_site_parents)
    cut_geo = TreeGeometry(parents, geo.rest_joints[keep], sites, geo.rest_end_sites)
    with pytest.raises(JointMappingError, match=shifted) as info:
        map_joints([clip.names[k] for k in keep], cut_geo, path="cut.bvh")
    assert info.value.missing == (cut,)
    assert f"lacks {cut}" in str(info.value)


def test_a_few_family_names_on_a_custom_rig_do_not_veto_its_layout(motion_fixtures: Path) -> None:
    """Only a family the names nearly complete speaks for a skeleton: a custom rig whose spine
    happens to be named Spine1, Spine2, Spine3 still maps by its tree."""
    clip = read_bvh(motion_fixtures / "unknown_names.bvh", max_frames=1)
    spine = {"bone_01": "Spine1", "bone_02": "Spine2", "bone_03": "Spine3"}
    names = [spine.get(n, n) for n in clip.names]
    jm = map_joints(names, clip_geometry(clip))
    assert jm.family == nf.AUTOMATIC
    assert jm.source_names(names)["Spine"] == "Spine1"
