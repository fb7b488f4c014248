"""Armature topologies: pruning to the end-effectors, chain order, neighbourhoods, pooling to
the primal skeleton, and homeomorphism between skeletons of different joint counts."""

from __future__ import annotations

import pytest

from robot_retarget.skeleton.armatures import (
    ROOT,
    ArmatureTopology,
    PoolLevel,
    TopologyError,
    canonical_topology,
    check_homeomorphic,
)


def _tree(edges: list[tuple[str, str | None]]) -> tuple[list[str], list[int]]:
    names = [n for n, _ in edges]
    return names, [-1 if p is None else names.index(p) for _, p in edges]


# A DAZ-like skeleton: right side first, two spine joints, no toes, fingers and eyes.
DAZ_LIKE = _tree(
    [
        ("hip", None),
        ("abdomen", "hip"),
        ("chest", "abdomen"),
        ("neck", "chest"),
        ("head", "neck"),
        ("lEye", "head"),
        ("rEye", "head"),
        ("rCollar", "chest"),
        ("rShldr", "rCollar"),
        ("rForeArm", "rShldr"),
        ("rHand", "rForeArm"),
        ("rThumb1", "rHand"),
        ("rIndex1", "rHand"),
        ("lCollar", "chest"),
        ("lShldr", "lCollar"),
        ("lForeArm", "lShldr"),
        ("lHand", "lForeArm"),
        ("lThumb1", "lHand"),
        ("rThigh", "hip"),
        ("rShin", "rThigh"),
        ("rFoot", "rShin"),
        ("lThigh", "hip"),
        ("lShin", "lThigh"),
        ("lFoot", "lShin"),
    ]
)


def _ends(names: list[str], *ends: str) -> list[int]:
    return [names.index(e) for e in ends]


def _canonical() -> ArmatureTopology:
    return canonical_topology()


def _daz() -> ArmatureTopology:
    names, parents = DAZ_LIKE
    ends = _ends(names, "lFoot", "rFoot", "head", "lHand", "rHand")
    return ArmatureTopology.from_tree("daz-like", names, parents, ends)


def test_canonical_armatures_chains_and_levels() -> None:
    topo = _canonical()
    assert topo.num_armatures == 22
    assert topo.armature_names[0] == "Hips"
    # Chains in end-effector order: legs, spine, neck, arms.
    firsts = [topo.armature_names[c[0]] for c in topo.chains]
    assert firsts == ["LeftUpLeg", "RightUpLeg", "Spine", "Neck", "LeftShoulder", "RightShoulder"]
    assert topo.primal_signature == (-1, -1, -1, 2, 2, 2)
    assert [lvl.size for lvl in topo.levels(2)] == [22, 12, 7]


def test_fingers_and_eyes_are_pruned_and_sides_are_ordered() -> None:
    topo = _daz()
    kept = set(topo.armature_names)
    assert not kept & {"lEye", "rEye", "rThumb1", "rIndex1", "lThumb1"}
    firsts = [topo.armature_names[c[0]] for c in topo.chains]
    # Left before right although the file lists the right side first.
    assert firsts == ["lThigh", "rThigh", "abdomen", "neck", "lCollar", "rCollar"]


def test_different_joint_counts_pool_to_one_primal_skeleton() -> None:
    canonical, daz = _canonical(), _daz()
    assert canonical.num_armatures != daz.num_armatures
    check_homeomorphic([canonical, daz])
    assert canonical.levels(2)[-1] == daz.levels(2)[-1]


def test_arms_on_different_joints_are_not_homeomorphic() -> None:
    names, parents = _tree(
        [
            ("hips", None),
            ("spine", "hips"),
            ("chest", "spine"),
            ("neck", "chest"),
            ("head", "neck"),
            ("lArm", "spine"),  # one arm hangs from the spine, the other from the chest
            ("lHand", "lArm"),
            ("rArm", "chest"),
            ("rHand", "rArm"),
            ("lLeg", "hips"),
            ("lFoot", "lLeg"),
            ("rLeg", "hips"),
            ("rFoot", "rLeg"),
        ]
    )
    odd = ArmatureTopology.from_tree(
        "odd", names, parents, _ends(names, "lFoot", "rFoot", "head", "lHand", "rHand")
    )
    with pytest.raises(TopologyError, match="odd: not homeomorphic") as info:
        check_homeomorphic([_canonical(), odd])
    assert info.value.skeleton == "odd"


def test_pooling_covers_every_armature_once_and_keeps_the_root_alone() -> None:
    topo = _daz()
    below = topo.num_armatures
    for groups in topo.pooling(3):
        members = sorted(a for g in groups for a in g)
        assert members == list(range(below))
        assert groups[ROOT] == (ROOT,)
        assert all(len(g) <= 2 for g in groups[1:]) or groups is topo.pooling(3)[-1]
        below = len(groups)
    assert below == 1 + len(topo.chains)


@pytest.mark.parametrize("topology", [_canonical(), _daz()], ids=["canonical", "daz"])
def test_neighbourhoods_are_symmetric_and_grow_with_distance(topology: ArmatureTopology) -> None:
    for level in topology.levels(2):
        near = {d: level.neighbours(d) for d in range(4)}
        for a in range(level.size):
            assert near[0][a] == (a,)
            for d in range(3):
                assert set(near[d][a]) <= set(near[d + 1][a])
            for b in near[2][a]:
                assert a in near[2][b]


def test_neighbours_of_a_chain_and_of_the_root() -> None:
    # root armature 0; 1 → 2 → 3 a chain; 4 another armature leaving the root
    level = PoolLevel((-1, 0, 1, 2, 0))
    assert level.neighbours(1)[2] == (1, 2, 3)
    assert level.neighbours(1)[1] == (0, 1, 2, 4)  # siblings share the root joint
    assert level.neighbours(1)[0] == (0, 1, 4)


def test_spec_round_trip_is_the_same_structure() -> None:
    topo = _daz()
    again = ArmatureTopology.from_spec(topo.spec())
    assert again.same_structure(topo)
    assert again.chains == topo.chains
    assert not again.same_structure(_canonical())


def test_bad_end_effectors_are_named() -> None:
    names, parents = DAZ_LIKE
    with pytest.raises(TopologyError, match="needs 5 end-effectors"):
        ArmatureTopology.from_tree("x", names, parents, [1, 2])
    below = _ends(names, "lShin", "lFoot", "head", "lHand", "rHand")
    with pytest.raises(TopologyError, match="'lShin' has another end-effector below it"):
        ArmatureTopology.from_tree("x", names, parents, below)
    with pytest.raises(TopologyError, match="bad topology spec"):
        ArmatureTopology.from_spec({"name": "y", "joint_names": ["a"]})
