"""Naming-family tables: lookup, prefixes and case."""

from __future__ import annotations

from robot_retarget.motion import name_families as nf
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS


def test_every_table_covers_every_canonical_joint() -> None:
    for table in nf.FAMILY_TABLES.values():
        assert set(table) == set(CANONICAL_JOINTS)


def test_right_side_is_derived_from_left() -> None:
    assert nf.FAMILY_TABLES[nf.DAZ]["RightArm"] == ("rShldr", "rShldrBend")
    assert nf.FAMILY_TABLES[nf.CMU_ASF]["RightToeBase"] == ("rtoes",)
    assert nf.FAMILY_TABLES[nf.MIXAMO]["RightHand"] == ("RightHand",)


def test_normalize_drops_namespace_and_case() -> None:
    assert nf.normalize_name("mixamorig:LeftArm") == "leftarm"
    assert nf.normalize_name("  Hips ") == "hips"


def test_lookup_takes_the_first_present_candidate() -> None:
    names = ("Hips", "LowerBack", "Neck", "Neck1", "mixamorig:Head")
    found = nf.lookup(nf.FAMILY_TABLES[nf.CMU_MOTIONBUILDER], names)
    assert found["Neck"] == 3  # Neck1 is preferred over Neck
    assert found["Head"] == 4
    assert "Spine1" not in found


def test_signatures_tell_motionbuilder_from_mixamo() -> None:
    mb = ("Hips", "LHipJoint", "LowerBack", "Neck1")
    assert nf.signature_hits(nf.CMU_MOTIONBUILDER, mb) == 3
    assert nf.signature_hits(nf.MIXAMO, mb) == 0
