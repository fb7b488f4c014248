"""Torch skeleton FK: agreement with numpy FK (acceptance: 1e-9 in float64), batching,
per-sample offsets, gradients, the module wrapper and errors."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as npq
from robot_retarget.nn import fk_torch
from robot_retarget.nn import quaternion_torch as tq
from robot_retarget.skeleton import Skeleton, default_canonical_skeleton
from robot_retarget.skeleton import forward_kinematics as np_fk
from robot_retarget.skeleton import local_from_global as np_local_from_global

FloatArray = npt.NDArray[np.float64]
DEVICES = ["cpu", *(["cuda"] if torch.cuda.is_available() else [])]


def t64(x: npt.ArrayLike) -> torch.Tensor:
    return torch.as_tensor(np.ascontiguousarray(x, dtype=np.float64))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(2718)


@pytest.fixture
def canonical() -> Skeleton:
    return default_canonical_skeleton()


@st.composite
def random_trees(draw: st.DrawFn, max_joints: int = 15) -> Skeleton:
    n = draw(st.integers(1, max_joints))
    parents = [-1] + [draw(st.integers(0, i - 1)) for i in range(1, n)]
    offsets = draw(arrays(np.float64, (n, 3), elements=st.floats(-2.0, 2.0)))
    return Skeleton(tuple(f"j{i}" for i in range(n)), tuple(parents), offsets)


# --- acceptance: numpy FK and torch FK agree to 1e-9 (float64) ----------------------------


@settings(max_examples=100, deadline=None)
@given(random_trees(), st.integers(0, 2**32 - 1))
def test_agrees_with_numpy_on_random_trees(skel: Skeleton, seed: int) -> None:
    rng = np.random.default_rng(seed)
    local = npq.normalize(rng.normal(size=(2, 3, skel.num_joints, 4)))
    root = rng.normal(size=(2, 3, 3))
    pos, glob = np_fk(skel, local, root)
    tpos, tglob = fk_torch.forward_kinematics(skel, None, t64(local), t64(root))
    np.testing.assert_allclose(tpos.numpy(), pos, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(tglob.numpy(), glob, rtol=0.0, atol=1e-9)


def test_agrees_with_numpy_on_the_canonical_skeleton(
    canonical: Skeleton, rng: np.random.Generator
) -> None:
    local = npq.normalize(rng.normal(size=(8, 30, canonical.num_joints, 4)))
    root = rng.normal(size=(8, 30, 3))
    pos, glob = np_fk(canonical, local, root)
    tpos, tglob = fk_torch.forward_kinematics(canonical, None, t64(local), t64(root))
    assert tpos.shape == (8, 30, 22, 3)
    assert tglob.shape == (8, 30, 22, 4)
    np.testing.assert_allclose(tpos.numpy(), pos, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(tglob.numpy(), glob, rtol=0.0, atol=1e-9)
    # Same through the index-list form with explicit offsets.
    tpos2, tglob2 = fk_torch.forward_kinematics(
        canonical.parents, canonical.offsets, t64(local), t64(root)
    )
    assert torch.equal(tpos2, tpos)
    assert torch.equal(tglob2, tglob)


def test_per_sample_offsets(canonical: Skeleton, rng: np.random.Generator) -> None:
    # Offsets (B, J, 3) with rotations (B, T, J, 4): one skeleton per sample, shared over time.
    local = npq.normalize(rng.normal(size=(4, 6, canonical.num_joints, 4)))
    offsets = canonical.offsets * rng.uniform(0.3, 2.0, size=(4, 1, 1))
    tpos, tglob = fk_torch.forward_kinematics(canonical.parents, t64(offsets), t64(local))
    for b in range(4):
        pos, glob = np_fk(canonical.with_offsets(offsets[b]), local[b])
        np.testing.assert_allclose(tpos[b].numpy(), pos, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(tglob[b].numpy(), glob, rtol=0.0, atol=1e-9)
    # The full (B, T, J, 3) form gives the same.
    full = np.broadcast_to(offsets[:, None], (4, 6, canonical.num_joints, 3))
    tpos_full, _ = fk_torch.forward_kinematics(canonical.parents, t64(full), t64(local))
    np.testing.assert_allclose(tpos_full.numpy(), tpos.numpy(), rtol=0.0, atol=1e-15)


def test_one_pose_many_skeletons_broadcasts(canonical: Skeleton, rng: np.random.Generator) -> None:
    local = npq.normalize(rng.normal(size=(1, canonical.num_joints, 4)))
    offsets = canonical.offsets * rng.uniform(0.5, 1.5, size=(5, 1, 1))
    tpos, tglob = fk_torch.forward_kinematics(canonical.parents, t64(offsets), t64(local))
    assert tpos.shape == (5, 22, 3)
    assert tglob.shape == (5, 22, 4)
    pos, _ = np_fk(canonical.with_offsets(offsets[3]), local[0])
    np.testing.assert_allclose(tpos[3].numpy(), pos, rtol=0.0, atol=1e-9)


def test_identity_pose_is_the_rest_pose(canonical: Skeleton) -> None:
    local = tq.identity((canonical.num_joints,), dtype=torch.float64)
    pos, glob = fk_torch.forward_kinematics(canonical, None, local, t64([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(pos.numpy(), canonical.rest_positions() + np.array([1.0, 2.0, 3.0]))
    assert torch.equal(glob, local)


def test_local_from_global_agrees_and_inverts(
    canonical: Skeleton, rng: np.random.Generator
) -> None:
    local = npq.normalize(rng.normal(size=(3, canonical.num_joints, 4)))
    _, glob = fk_torch.forward_kinematics(canonical, None, t64(local))
    back = fk_torch.local_from_global(canonical, glob)
    np.testing.assert_allclose(back.numpy(), local, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(
        back.numpy(), np_local_from_global(canonical, glob.numpy()), rtol=0.0, atol=1e-15
    )
    back_list = fk_torch.local_from_global(list(canonical.parents), glob)
    assert torch.equal(back_list, back)


def test_depth_levels(canonical: Skeleton) -> None:
    levels = fk_torch.depth_levels(canonical.parents)
    assert len(levels) == 8  # Hips → Spine → Spine1 → Spine2 → Shoulder → Arm → ForeArm → Hand
    assert sorted(j for level in levels for j in level) == list(range(canonical.num_joints))
    depth = {j: d for d, level in enumerate(levels) for j in level}
    assert all(depth[j] == depth[p] + 1 for j, p in enumerate(canonical.parents) if p >= 0)
    assert fk_torch.depth_levels([-1]) == ((0,),)


# --- gradients ------------------------------------------------------------------------------


def test_gradcheck_through_rotations_offsets_and_root() -> None:
    parents = (-1, 0, 1, 1, 3)
    gen = torch.Generator().manual_seed(3)
    raw = torch.randn(2, 5, 4, dtype=torch.float64, generator=gen, requires_grad=True)
    offsets = torch.randn(2, 5, 3, dtype=torch.float64, generator=gen, requires_grad=True)
    root = torch.randn(2, 3, dtype=torch.float64, generator=gen, requires_grad=True)

    def fk(q: torch.Tensor, s: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
        pos, glob = fk_torch.forward_kinematics(parents, s, tq.normalize(q), r)
        return torch.cat([pos, glob], dim=-1)

    assert torch.autograd.gradcheck(fk, (raw, offsets, root), eps=1e-6, atol=1e-6)


def test_gradients_finite_at_identity_and_reach_every_joint(canonical: Skeleton) -> None:
    local = tq.identity((2, canonical.num_joints), dtype=torch.float64).requires_grad_(True)
    pos, _ = fk_torch.forward_kinematics(canonical, None, local)
    pos[..., 9, :].sum().backward()  # left hand: depends on its chain only
    assert local.grad is not None
    assert torch.all(torch.isfinite(local.grad))
    touched = {int(j) for j in torch.nonzero(local.grad.abs().sum(dim=(0, 2))).flatten()}
    assert touched <= {0, 1, 2, 3, 6, 7, 8}  # Hips … LeftForeArm; the hand's own rotation: no
    assert {6, 7, 8} <= touched


def test_gradient_moves_hand_toward_target(canonical: Skeleton) -> None:
    # One gradient step on a position loss lowers it: the layer is usable for IK-style losses.
    local = tq.identity((canonical.num_joints,), dtype=torch.float64).requires_grad_(True)
    target = t64([0.3, 1.0, 0.4])
    pos, _ = fk_torch.forward_kinematics(canonical, None, tq.normalize(local))
    loss = torch.sum((pos[9] - target) ** 2)
    loss.backward()
    assert local.grad is not None
    with torch.no_grad():
        stepped = tq.normalize(local - 0.05 * local.grad)
        pos2, _ = fk_torch.forward_kinematics(canonical, None, stepped)
    assert torch.sum((pos2[9] - target) ** 2) < loss


# --- module, dtypes, devices ----------------------------------------------------------------


@pytest.mark.parametrize("device", DEVICES)
def test_module_float32_on_every_device(
    canonical: Skeleton, rng: np.random.Generator, device: str
) -> None:
    layer = fk_torch.SkeletonFK(canonical).to(device=device, dtype=torch.float32)
    assert list(layer.parameters()) == []  # offsets are a buffer, not trained
    assert layer.offsets.dtype == torch.float32
    local = npq.normalize(rng.normal(size=(3, 4, canonical.num_joints, 4)))
    root = rng.normal(size=(3, 4, 3))
    q32 = torch.as_tensor(local, dtype=torch.float32, device=device)
    pos, glob = layer(q32, torch.as_tensor(root, dtype=torch.float32, device=device))
    assert pos.dtype == glob.dtype == torch.float32
    assert pos.device.type == device
    assert pos.is_contiguous()
    assert glob.is_contiguous()
    ref_pos, ref_glob = np_fk(canonical, local, root)
    np.testing.assert_allclose(pos.double().cpu().numpy(), ref_pos, atol=1e-5)
    np.testing.assert_allclose(glob.double().cpu().numpy(), ref_glob, atol=1e-5)
    # Per-call offsets override the buffer.
    scaled = torch.as_tensor(canonical.offsets * 2.0, dtype=torch.float32, device=device)
    pos2, _ = layer(q32, None, scaled)
    ref2, _ = np_fk(canonical.scaled(2.0), local)
    np.testing.assert_allclose(pos2.double().cpu().numpy(), ref2, atol=1e-5)


def test_state_dict_holds_the_offsets(canonical: Skeleton) -> None:
    layer = fk_torch.SkeletonFK(canonical)
    np.testing.assert_array_equal(layer.state_dict()["offsets"].numpy(), canonical.offsets)


# --- errors ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("parents", "match"),
    [
        ((0, 0), "root"),
        ((-1, 1), "parents must come before"),
        ((-1, 0, 3, 1), "parent 3"),
        ((), "root"),
    ],
)
def test_bad_parents_raise(parents: tuple[int, ...], match: str) -> None:
    n = max(len(parents), 1)
    with pytest.raises(ValueError, match=match):
        fk_torch.forward_kinematics(parents, torch.zeros(n, 3), tq.identity((n,)))


def test_shape_errors(canonical: Skeleton) -> None:
    q = tq.identity((5, canonical.num_joints), dtype=torch.float64)
    with pytest.raises(ValueError, match=r"\(\.\.\., 22, 4\)"):
        fk_torch.forward_kinematics(canonical, None, q[..., :21, :])
    with pytest.raises(ValueError, match="offsets are required"):
        fk_torch.forward_kinematics(canonical.parents, None, q)
    with pytest.raises(ValueError, match="offsets must have shape"):
        fk_torch.forward_kinematics(canonical, torch.zeros(21, 3), q)
    with pytest.raises(ValueError, match="offsets must have shape"):
        fk_torch.forward_kinematics(canonical, torch.zeros(1, 5, 22, 3), q)
    with pytest.raises(ValueError, match="do not broadcast"):
        fk_torch.forward_kinematics(canonical, torch.zeros(4, 22, 3), q)
    with pytest.raises(ValueError, match=r"\(\.\.\., 22, 4\)"):
        fk_torch.local_from_global(canonical, q[..., :3])
    with pytest.raises(ValueError, match="root_pos"):
        fk_torch.forward_kinematics(canonical, None, q, torch.zeros(5, 2, dtype=torch.float64))
    with pytest.raises(ValueError, match="root_pos"):
        fk_torch.forward_kinematics(canonical, None, q, torch.zeros(4, 3, dtype=torch.float64))


def test_fk_trains_after_a_first_call_under_inference_mode() -> None:
    """The per-level index cache must not hold inference tensors (regression): training with
    learnable offsets after a validation pass under inference_mode used to fail."""
    parents = (-1, 0, 1, 1, 3)
    fk_torch._level_indices.cache_clear()  # the first build must happen in inference mode
    with torch.inference_mode():
        fk_torch.forward_kinematics(
            parents, torch.ones(5, 3, dtype=torch.float64), torch.tensor([[1.0, 0, 0, 0]] * 5)
        )
    offsets = torch.ones(5, 3, dtype=torch.float64, requires_grad=True)
    q = torch.tensor([[1.0, 0.1, 0, 0]] * 5, dtype=torch.float64, requires_grad=True)
    pos, _ = fk_torch.forward_kinematics(parents, offsets, q)
    pos.sum().backward()
    assert q.grad is not None
    assert offsets.grad is not None
    assert torch.isfinite(offsets.grad).all()
