"""A BVH clip on its own skeleton: the file's joints and rotations, frame for frame with the
canonical motion, in metres; resampled as HumanMotion resamples."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.motion.bvh import read_bvh
from robot_retarget.motion.canonicalize import canonicalize
from robot_retarget.motion.native_pose import native_pose
from robot_retarget.motion.units import unit_scale_m

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"


def test_the_files_own_joints_and_rotations() -> None:
    clip = read_bvh(FIXTURES / "asf_names.bvh")
    motion = canonicalize(clip)
    pose = native_pose(clip, motion)
    names = pose.topology.armature_names
    assert names[0] == clip.names[0]
    assert len(names) > 22 - 1  # more joints than the canonical skeleton keeps
    assert not [n for n in names if "finger" in n.lower() or "thumb" in n.lower()]
    assert pose.num_frames == motion.num_frames
    first = motion.tpose_frames_dropped
    expected = clip.local_rotations()[first:, list(pose.topology.joints[1:])]
    dots = np.abs(np.sum(expected * pose.local_quats, axis=-1))
    assert np.allclose(dots, 1.0, atol=1e-9)  # the same rotations (up to sign: made continuous)


def test_offsets_are_metres() -> None:
    clip = read_bvh(FIXTURES / "tiny_walk.bvh")
    motion = canonicalize(clip)
    pose = native_pose(clip, motion)
    joints = list(pose.topology.joints[1:])
    assert np.allclose(pose.offsets, clip.offsets[joints] * unit_scale_m(motion.unit))
    bones = np.linalg.norm(pose.offsets, axis=-1)
    assert 0.2 < bones.max() < 0.7  # a thigh or shin, in metres


def test_resampling_matches_the_canonical_motion() -> None:
    clip = read_bvh(FIXTURES / "tiny_walk.bvh")
    motion = canonicalize(clip)
    pose = native_pose(clip, motion)
    slower = pose.resample(motion.fps, 0.5 * motion.fps)
    assert slower.num_frames == motion.resample(0.5 * motion.fps).num_frames
    assert np.allclose(slower.local_quats[1], pose.local_quats[2])
