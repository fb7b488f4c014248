"""The residual model's geometric losses equal the eval metrics they make differentiable."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.evaluation import metrics
from robot_retarget.evaluation.foot_contact import foot_contacts as np_foot_contacts
from robot_retarget.evaluation.foot_contact import foot_skate
from robot_retarget.evaluation.skeleton_measures import leg_length, skeleton_height
from robot_retarget.geometry import quaternion as quat
from robot_retarget.nn.corruption import CorruptionRanges, corrupt_batch
from robot_retarget.nn.retarget_losses import (
    bone_direction_loss,
    contact_loss,
    denoising_loss,
    effector_loss,
    foot_contacts,
    foot_skate_loss,
)
from robot_retarget.skeleton.canonical import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    default_canonical_skeleton,
)
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

HUMAN = default_canonical_skeleton()


def _robot_like() -> Skeleton:
    offsets = np.asarray(HUMAN.offsets) * 0.35
    offsets[[7, 8, 9, 11, 12, 13]] *= 0.7  # short arms
    offsets[1] *= 1.4
    return Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets)


def _walk(seed: int, frames: int = 40, speed: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    rotvec = 0.4 * rng.normal(size=(1, 22, 3)) + speed * 0.05 * np.cumsum(
        rng.normal(size=(frames, 22, 3)), axis=0
    )
    root = np.cumsum(speed * 0.02 * rng.normal(size=(frames, 3)), axis=0) + np.array([0, 0.9, 0])
    return quat.from_rotation_vector(rotvec), root


def _positions(skel: Skeleton, q: np.ndarray, root: np.ndarray) -> np.ndarray:
    return np.asarray(forward_kinematics(skel, q, root)[0])


def _t(a: np.ndarray) -> torch.Tensor:
    return torch.tensor(np.asarray(a), dtype=torch.float64)[None]


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_losses_equal_the_metrics(seed: int) -> None:
    src_q, src_root = _walk(seed)
    tgt_q, _ = _walk(seed + 1)
    robot = _robot_like()
    src_pos = _positions(HUMAN, src_q, src_root)
    tgt_pos = _positions(robot, tgt_q, src_root * 0.35)
    args = (_t(src_pos), _t(HUMAN.offsets), _t(tgt_pos), _t(robot.offsets))
    assert float(effector_loss(*args)[0]) == pytest.approx(
        metrics.end_effector_error(src_pos, HUMAN, tgt_pos, robot), abs=1e-4
    )
    assert float(contact_loss(*args)[0]) == pytest.approx(
        metrics.contact_distance_error(src_pos, HUMAN, tgt_pos, robot), abs=1e-4
    )
    assert math.degrees(float(bone_direction_loss(*args)[0])) == pytest.approx(
        metrics.bone_direction_error_deg(src_pos, HUMAN, tgt_pos, robot), abs=1e-2
    )


def test_foot_contacts_and_skate_equal_the_metrics() -> None:
    q, root = _walk(3, frames=60, speed=0.1)  # slow: some frames count as planted
    pos = _positions(HUMAN, q, root)
    contacts = np_foot_contacts(pos, 30.0, leg_length(HUMAN))
    ours = foot_contacts(_t(pos), 30.0, _t(HUMAN.offsets))[0].numpy()
    np.testing.assert_array_equal(ours, contacts)
    assert contacts.any()
    other = _positions(HUMAN, _walk(4, frames=60)[0], root)
    expected = foot_skate(other, contacts, 30.0, leg_length(HUMAN))
    got = float(foot_skate_loss(_t(other), torch.tensor(contacts)[None], 30.0, _t(HUMAN.offsets)))
    assert got == pytest.approx(expected, rel=5e-3)  # the smoothed norm, ε = 0.1 mm


def test_denoising_loss_is_the_metric() -> None:
    q, root = _walk(5)
    a = _positions(HUMAN, q, root)
    b = a + np.random.default_rng(0).normal(0.0, 0.01, size=a.shape)
    got = float(denoising_loss(_t(b), _t(a), _t(HUMAN.offsets))[0])
    assert got == pytest.approx(metrics.position_error(b, a, skeleton_height(HUMAN)))


def test_a_motion_on_its_own_skeleton_costs_nothing() -> None:
    q, root = _walk(6)
    pos = _t(_positions(HUMAN, q, root))
    offs = _t(HUMAN.offsets)
    for loss in (effector_loss, contact_loss, bone_direction_loss):
        assert float(loss(pos, offs, pos, offs)[0]) < 1e-6


def test_losses_have_finite_gradients_at_zero_error() -> None:
    q, root = _walk(7)
    pos = _t(_positions(HUMAN, q, root)).requires_grad_(True)
    offs = _t(HUMAN.offsets)
    total = sum(
        loss(pos.detach(), offs, pos, offs).sum()
        for loss in (effector_loss, contact_loss, bone_direction_loss)
    )
    total.backward()
    assert pos.grad is not None
    assert torch.isfinite(pos.grad).all()


def test_corruption_leaves_clean_samples_and_the_root_orientation_alone() -> None:
    q, root = _walk(8)
    quats = _t(q).repeat(4, 1, 1, 1)
    roots = _t(root).repeat(4, 1, 1)
    heights = torch.full((4,), 1.7, dtype=torch.float64)
    gen = torch.Generator().manual_seed(0)
    clean_q, clean_root = corrupt_batch(quats, roots, heights, CorruptionRanges(p_clean=1.0), gen)
    torch.testing.assert_close(clean_q, quats)
    torch.testing.assert_close(clean_root, roots)
    noisy_q, noisy_root = corrupt_batch(
        quats, roots, heights, CorruptionRanges(sigma_frac=(0.01, 0.01), zero_prob=(0.5, 0.5)), gen
    )
    torch.testing.assert_close(noisy_q[..., 0, :], quats[..., 0, :])
    zeroed = (noisy_q[..., 1:, 0] == 1.0).double().mean()
    assert 0.4 < float(zeroed) < 0.6
    # Root noise: σ = 0.01 × height per axis.
    assert float((noisy_root - roots).std()) == pytest.approx(0.017, rel=0.15)
