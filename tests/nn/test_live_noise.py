"""Live-sender corruption for training: what the live path would make of a corrupted position
stream, reproducible, and only where it is asked for."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.nn.live_noise import LiveNoise, corrupt_live
from robot_retarget.sources.from_positions import PositionsToRotations

_QUIET = LiveNoise(jitter=(0.0, 0.0), p_freeze=0.0, p_swap=0.0, p_bone_length=0.0)
_LOUD = LiveNoise(jitter=(1.0, 1.5), p_freeze=1.0, p_swap=1.0, p_bone_length=1.0)


def _batch(b: int = 3, t: int = 40) -> tuple[torch.Tensor, ...]:
    m = demo_motion(fps=30.0).frames(0, t)
    q = torch.tensor(np.repeat(m.local_quats[None], b, 0))
    root = torch.tensor(np.repeat(m.root_pos[None], b, 0))
    offsets = torch.tensor(np.repeat(m.skeleton.offsets[None], b, 0))
    return q, root, offsets, torch.full((b,), m.height_m, dtype=torch.float64)


def test_without_noise_it_is_the_live_solve_of_the_clean_positions() -> None:
    """What a clean position sender delivers: twist-free rotations, the same root."""
    m = demo_motion(fps=30.0).frames(0, 40)
    q, root, offsets, heights = _batch(1)
    got_q, got_root = corrupt_live(q, root, offsets, heights, _QUIET, 30.0)
    solver = PositionsToRotations(m.skeleton)
    want = np.stack([solver.solve(p)[0] for p in m.positions()])
    sign = np.where(np.sum(got_q[0].numpy() * want, -1, keepdims=True) < 0, -1.0, 1.0)
    np.testing.assert_allclose(got_q[0].numpy() * sign, want, atol=1e-9)
    np.testing.assert_allclose(got_root[0].numpy(), m.root_pos, atol=1e-12)


def test_loud_noise_gives_unit_rotations_that_differ_and_is_reproducible() -> None:
    q, root, offsets, heights = _batch()
    runs = [
        corrupt_live(q, root, offsets, heights, _LOUD, 30.0, torch.Generator().manual_seed(3))
        for _ in range(2)
    ]
    (a_q, a_root), (b_q, b_root) = runs
    assert torch.equal(a_q, b_q)
    assert torch.equal(a_root, b_root)
    assert torch.isfinite(a_q).all()
    torch.testing.assert_close(a_q.norm(dim=-1), torch.ones(a_q.shape[:-1], dtype=a_q.dtype))
    clean_q, _ = corrupt_live(q, root, offsets, heights, _QUIET, 30.0)
    angle = 2 * torch.acos((a_q * clean_q).sum(-1).abs().clamp(max=1.0))
    assert float(angle.mean()) > 0.02  # jitter of 1–1.5 % of the height moves every joint
    assert float((root - a_root).norm(dim=-1).mean()) > 1e-3


@pytest.mark.parametrize("fps", [30.0, 120.0])
def test_frozen_joints_change_only_their_intervals(fps: float) -> None:
    """Only freezing: six joints each hold a position for one interval of at most the
    evaluation's 30 frames at 120 fps (scaled to ``fps``); every other frame is the clean
    solve's, exactly."""
    q, root, offsets, heights = _batch(4, 200)
    freeze = LiveNoise(jitter=(0.0, 0.0), p_freeze=1.0, p_swap=0.0, p_bone_length=0.0)
    got, _ = corrupt_live(q, root, offsets, heights, freeze, fps, torch.Generator().manual_seed(0))
    clean, _ = corrupt_live(q, root, offsets, heights, _QUIET, fps)
    changed = ((got - clean).abs().amax(-1) > 0.0).any(-1)  # (B, T)
    assert bool(changed.any())
    longest = round(30 * fps / 120.0)
    assert (changed.sum(-1) <= 6 * longest).all()
