"""Foot lock: the IK reaches, a planted foot stays planted, and the frame path equals the clip."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robot_retarget.evaluation.foot_contact import foot_contacts, foot_skate
from robot_retarget.evaluation.skeleton_measures import leg_length
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.features import apply_heading, compute_features, integrate_root
from robot_retarget.nn.fk_torch import forward_kinematics
from robot_retarget.nn.models.foot_lock import ANKLES, LEGS, FootLock, two_bone_ik
from robot_retarget.nn.retarget_losses import limb_lengths
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.skeleton import Skeleton
from robot_retarget.skeleton.skeleton import forward_kinematics as numpy_fk

vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.2)


@settings(max_examples=60, deadline=None)
@given(thigh=vectors, shin=vectors, aim=vectors, reach=st.floats(0.1, 0.95))
def test_two_bone_ik_reaches_any_reachable_target(
    thigh: tuple[float, float, float],
    shin: tuple[float, float, float],
    aim: tuple[float, float, float],
    reach: float,
) -> None:
    hip = torch.zeros(3, dtype=torch.float64)
    knee = hip + torch.tensor(thigh, dtype=torch.float64)
    ankle = knee + torch.tensor(shin, dtype=torch.float64)
    l1, l2 = float(torch.linalg.norm(knee - hip)), float(torch.linalg.norm(ankle - knee))
    lo, hi = abs(l1 - l2), l1 + l2
    # A knee within a few degrees of straight or of folded starts from the clamp's bend (see
    # two_bone_ik): the hip-ankle distance stays 1e-3 of the leg's length inside its range.
    d0 = float(torch.linalg.norm(ankle - hip))
    assume(lo + 1e-3 * hi < d0 < hi * (1.0 - 1e-3))
    direction = torch.tensor(aim, dtype=torch.float64)
    target = hip + direction / torch.linalg.norm(direction) * (lo + reach * (hi - lo))
    # A knee's hinge is square to the thigh, as a real knee's (it decides a straight or a
    # folded leg's bend; along the bone it could not turn the shin at all).
    along_z = abs(thigh[2]) / float(np.linalg.norm(thigh)) > 0.9
    helper = torch.tensor([1.0, 0.0, 0.0] if along_z else [0.0, 0.0, 1.0])
    hinge = torch.linalg.cross(knee - hip, helper.double(), dim=-1)
    r_hip, r_knee = two_bone_ik(hip, knee, ankle, target, hinge / torch.linalg.norm(hinge))
    new_knee = hip + qt.rotate(r_hip, knee - hip)
    new_ankle = new_knee + qt.rotate(r_hip, qt.rotate(r_knee, ankle - knee))
    assert float(torch.linalg.norm(new_ankle - target)) < 1e-3 * hi


def test_two_bone_ik_leaves_a_leg_at_its_target_alone() -> None:
    hip = torch.tensor([0.1, 0.0, 0.0])
    knee = torch.tensor([0.1, -0.4, 0.05])
    ankle = torch.tensor([0.1, -0.8, -0.05])
    r_hip, r_knee = two_bone_ik(hip, knee, ankle, ankle.clone(), torch.tensor([1.0, 0.0, 0.0]))
    identity = qt.identity(dtype=torch.float32)
    assert float(qt.angle_between(r_hip, identity)) < 1e-5
    assert float(qt.angle_between(r_knee, identity)) < 1e-5


def _demo_pair() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The demo motion's first 8 s (squats, side steps) and a target with long shins and short
    thighs: copy-scaled's feet slide wherever the performer's knees bend."""
    motion = demo_motion()
    frames = slice(0, 240)
    quats = torch.tensor(motion.local_quats[frames], dtype=torch.float64)[None]
    root = torch.tensor(motion.root_pos[frames], dtype=torch.float64)[None]
    src = torch.tensor(np.asarray(motion.skeleton.offsets), dtype=torch.float64)[None]
    tgt = src.clone() * 0.4
    for _hip, knee, ankle in LEGS:
        tgt[:, knee] *= 0.6
        tgt[:, ankle] *= 1.5
    return quats, root, src, tgt


def _lock_inputs(
    quats: torch.Tensor, root: torch.Tensor, src: torch.Tensor, tgt: torch.Tensor
) -> tuple[torch.Tensor, ...]:
    """Copy-scaled's output (heading-free rotations, root velocities) and the source's features."""
    feats = compute_features(quats, root, src)
    h_ratio = float(tgt[0, :, 1].abs().sum() / src[0, :, 1].abs().sum())
    vel = torch.cat([feats.root_vel[..., :3] * h_ratio, feats.root_vel[..., 3:]], dim=-1)
    return feats.local_quats, vel, feats.local_pos, feats.root_vel, limb_lengths(src)[1]


def _world(
    q: torch.Tensor, vel: torch.Tensor, offsets: torch.Tensor, root: torch.Tensor
) -> np.ndarray:
    pos, yaw = integrate_root(vel, root[:, 0], torch.zeros(1, dtype=vel.dtype))
    skel = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets[0].numpy())
    glob = apply_heading(q, yaw)
    return numpy_fk(skel, glob[0].numpy(), pos[0].numpy())[0]


def test_a_planted_foot_stays_planted_and_only_the_legs_turn() -> None:
    quats, root, src, tgt = _demo_pair()
    q, vel, src_pos, src_vel, leg = _lock_inputs(quats, root, src, tgt)
    with torch.no_grad():
        locked = FootLock()(q, vel, tgt, src_pos, src_vel, leg)
    src_skel = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, src[0].numpy())
    src_world = numpy_fk(src_skel, quats[0].numpy(), root[0].numpy())[0]
    contacts = foot_contacts(src_world, 30.0, leg_length(src_skel))
    tgt_skel = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, tgt[0].numpy())
    before = foot_skate(_world(q, vel, tgt, root), contacts, 30.0, leg_length(tgt_skel))
    after = foot_skate(_world(locked, vel, tgt, root), contacts, 30.0, leg_length(tgt_skel))
    assert after < 0.5 * before
    moved = qt.angle_between(locked, q)[0]  # (T, J)
    legs = [j for leg_joints in LEGS for j in leg_joints]
    assert float(moved[:, [j for j in range(22) if j not in legs]].max()) < 1e-6
    # The feet keep their global orientation; the bones their lengths (rotations only).
    _, g_before = forward_kinematics(CANONICAL_PARENTS, tgt, q)
    _, g_after = forward_kinematics(CANONICAL_PARENTS, tgt, locked)
    assert float(qt.angle_between(g_after[..., ANKLES, :], g_before[..., ANKLES, :]).max()) < 1e-6


def test_frame_by_frame_equals_the_clip() -> None:
    quats, root, src, tgt = _demo_pair()
    q, vel, src_pos, src_vel, leg = _lock_inputs(quats, root, src, tgt)
    lock = FootLock()
    with torch.no_grad():
        clip = lock(q, vel, tgt, src_pos, src_vel, leg)
        lock.reset()
        frames = [
            lock.step(q[:, t], vel[:, t], tgt, src_pos[:, t], src_vel[:, t], leg)
            for t in range(q.shape[1])
        ]
    assert float(qt.angle_between(torch.stack(frames, dim=1), clip).max()) < 1e-6


@pytest.mark.parametrize("lift", [0.0, 5.0])
def test_no_lock_without_contact(lift: float) -> None:
    """A performer whose feet rush along (or hang high) is never locked: the pose is unchanged."""
    quats, root, src, tgt = _demo_pair()
    fast = root.clone()
    fast[..., 2] += torch.arange(root.shape[1], dtype=root.dtype) * 0.2  # 6 m/s forward
    fast[..., 1] += lift * torch.arange(root.shape[1], dtype=root.dtype) / root.shape[1]
    q, vel, src_pos, src_vel, leg = _lock_inputs(quats, fast, src, tgt)
    with torch.no_grad():
        locked = FootLock()(q, vel, tgt, src_pos, src_vel, leg)
    assert float(qt.angle_between(locked, q).max()) < 1e-6
