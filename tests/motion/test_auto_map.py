"""Automatic mapping from topology and rest geometry."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.motion.auto_map import TreeGeometry, auto_map
from robot_retarget.motion.bvh import read_bvh
from robot_retarget.motion.canonicalize import clip_geometry
from robot_retarget.motion.joint_map import map_joints
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

# tests/fixtures/motion/generate.py names canonical role k "bone_%02d" (Hips is pelvis_j).
EXPECTED_UNKNOWN = {
    n: ("pelvis_j" if k == 0 else f"bone_{k:02d}") for k, n in enumerate(CANONICAL_JOINTS)
}


def names_of(result: dict[str, int], names: tuple[str, ...]) -> dict[str, str]:
    return {c: names[j] for c, j in result.items()}


def test_unknown_names_fixture_maps_every_joint(motion_fixtures: Path) -> None:
    clip = read_bvh(motion_fixtures / "unknown_names.bvh")
    result = auto_map(clip_geometry(clip))
    assert result.missing == ()
    assert names_of(result.joints, clip.names) == EXPECTED_UNKNOWN
    np.testing.assert_allclose(result.up, [0, 1, 0], atol=0.2)


def test_auto_map_agrees_with_name_tables_on_real_clips(mocap_dir: Path) -> None:
    for clip_name in ("02/02_01.bvh", "13/13_11.bvh"):
        clip = read_bvh(mocap_dir / clip_name, max_frames=2)
        geo = clip_geometry(clip)
        by_name = map_joints(clip.names, geo)
        auto = auto_map(geo)
        expected = {
            c: s
            for c, s in zip(CANONICAL_JOINTS, by_name.source_joints, strict=True)
            if s is not None
        }
        assert auto.joints == expected, clip_name


def test_mirrored_skeleton_swaps_sides(motion_fixtures: Path) -> None:
    """Mirroring X (toes still forward) must swap what is called left and right."""
    clip = read_bvh(motion_fixtures / "unknown_names.bvh")
    geo = clip_geometry(clip)
    flip = np.array([-1.0, 1.0, 1.0])
    mirrored = TreeGeometry(
        geo.parents, geo.rest_joints * flip, geo.end_site_parents, geo.rest_end_sites * flip
    )
    plain = auto_map(geo).joints
    swapped = auto_map(mirrored).joints
    assert swapped["LeftHand"] == plain["RightHand"]
    assert swapped["RightFoot"] == plain["LeftFoot"]


def test_facing_comes_from_the_toes(motion_fixtures: Path) -> None:
    """Turning the person 180° about Y keeps left/right: the toes say where forward is."""
    clip = read_bvh(motion_fixtures / "unknown_names.bvh")
    geo = clip_geometry(clip)
    turn = np.array([-1.0, 1.0, -1.0])
    turned = TreeGeometry(
        geo.parents, geo.rest_joints * turn, geo.end_site_parents, geo.rest_end_sites * turn
    )
    assert auto_map(turned).joints == auto_map(geo).joints


def test_too_simple_tree_maps_nothing() -> None:
    geo = TreeGeometry(
        (-1, 0, 1), np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0.0]]), (), np.zeros((0, 3))
    )
    result = auto_map(geo)
    assert result.joints == {}
    assert "Hips" in result.missing


def test_z_up_skeleton_maps_like_its_names(motion_fixtures: Path) -> None:
    clip = read_bvh(motion_fixtures / "z_up.bvh", max_frames=1)
    geo = clip_geometry(clip)
    result = auto_map(geo)
    np.testing.assert_allclose(result.up, [0, 0, 1], atol=0.2)
    by_name = map_joints(clip.names, geo)
    assert result.joints == dict(
        zip(CANONICAL_JOINTS, (s for s in by_name.source_joints if s is not None), strict=True)
    )
