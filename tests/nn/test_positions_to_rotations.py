"""The torch positions → rotations solve equals the live path's (numpy / compiled) solve."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn.positions_to_rotations import positions_to_rotations
from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    Joint,
    default_canonical_skeleton,
)
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics
from robot_retarget.sources.from_positions import PositionsToRotations


def _same_rotations(got: np.ndarray, want: np.ndarray, atol: float) -> None:
    sign = np.where(np.sum(got * want, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    np.testing.assert_allclose(got * sign, want, rtol=0, atol=atol)


def _solve_both(skeletons: list[Skeleton], positions: np.ndarray) -> None:
    """``positions`` (B, T, J, 3), one skeleton per sample."""
    offsets = torch.tensor(np.stack([s.offsets for s in skeletons]))
    got = positions_to_rotations(torch.tensor(positions), offsets).numpy()
    for b, skeleton in enumerate(skeletons):
        solver = PositionsToRotations(skeleton)
        want = np.stack([solver.solve(p)[0] for p in positions[b]])
        _same_rotations(got[b], want, 1e-9)


def test_the_demo_motion_solves_as_the_live_path() -> None:
    motion = demo_motion(fps=30.0).frames(0, 40)
    _solve_both([motion.skeleton], motion.positions()[None])


def _spine_at_hips() -> Skeleton:
    """A CMU MotionBuilder-like skeleton: Spine on the Hips (a zero-length bone), so the Hips'
    primary axis comes from further up, per sample."""
    offsets = default_canonical_skeleton().offsets.copy()
    offsets[Joint.Spine1] += offsets[Joint.Spine]
    offsets[Joint.Spine] = 0.0
    return Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets)


@settings(max_examples=20, deadline=None)
@given(
    arrays(np.float64, (2, 3, 22, 3), elements=st.floats(-1.2, 1.2)),
    st.floats(0.5, 2.0),
)
def test_any_pose_on_mixed_skeletons_solves_as_the_live_path(
    rotvecs: np.ndarray, scale: float
) -> None:
    """Random poses on two skeletons in one batch (one of them with Spine at the Hips)."""
    plain = default_canonical_skeleton()
    scaled = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, plain.offsets * scale)
    skeletons = [scaled, _spine_at_hips()]
    positions = np.stack(
        [
            forward_kinematics(s, quat.from_rotation_vector(r), np.zeros((len(r), 3)))[0]
            for s, r in zip(skeletons, rotvecs, strict=True)
        ]
    )
    _solve_both(skeletons, positions)
