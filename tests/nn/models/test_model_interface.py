"""Every registered model honours the RetargetModel contract (tiny random weights)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import torch

from robot_retarget.geometry import quaternion as quat
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.registry import model_names
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import forward_kinematics

Motion = Callable[..., tuple[torch.Tensor, torch.Tensor]]
ALL = model_names()


@pytest.mark.parametrize("name", ALL)
def test_output_shapes_and_unit_quaternions(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model(name).eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 12)
    out = model(quats, root, src, tgt)
    assert out.local_quats.shape == (2, 12, 22, 4)
    assert out.root_pos.shape == (2, 12, 3)
    assert out.features.local_pos.shape == (2, 12, 22, 3)
    assert out.features.root_vel.shape == (2, 12, 4)
    assert out.local_quats.dtype == torch.float32
    norms = torch.linalg.vector_norm(out.local_quats, dim=-1)
    torch.testing.assert_close(norms, torch.ones_like(norms), atol=1e-5, rtol=0)
    assert torch.isfinite(out.root_pos).all()
    # The target starts where the source starts.
    torch.testing.assert_close(out.root_pos[:, 0], root[:, 0])


@pytest.mark.parametrize("name", ALL)
def test_outputs_agree_with_numpy_fk(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """features.local_pos (the FK layer) is numpy FK of the output on the target skeleton,
    and the output's global pose is that local pose placed at the integrated root."""
    model = tiny_model(name).eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 8, seed=3)
    with torch.no_grad():
        out = model(quats, root, src, tgt)
    skel = default_canonical_skeleton()
    for b in range(2):
        offs = tgt[b].double().numpy()
        local, _ = forward_kinematics(
            skel, out.features.local_quats[b].double().numpy(), offsets=offs
        )
        np.testing.assert_allclose(out.features.local_pos[b].numpy(), local, atol=2e-5)
        glob, _ = forward_kinematics(
            skel,
            out.local_quats[b].double().numpy(),
            out.root_pos[b].double().numpy(),
            offsets=offs,
        )
        yaw = out.features.yaw[b].double().numpy()
        heading = np.stack(
            [np.cos(yaw / 2), np.zeros_like(yaw), np.sin(yaw / 2), np.zeros_like(yaw)], -1
        )
        expected = out.root_pos[b].double().numpy()[:, None] + quat.rotate(heading[:, None], local)
        np.testing.assert_allclose(glob, expected, atol=2e-5)


@pytest.mark.parametrize("name", ALL)
def test_online_step_matches_clip_path(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model(name).eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 10, seed=5)
    with torch.no_grad():
        clip = model(quats, root, src, tgt)
    for _ in range(2):  # reset() makes a second pass identical to the first
        model.reset()
        with torch.inference_mode():
            frames = [model.step(quats[:, t], root[:, t], src, tgt) for t in range(10)]
        step_q = torch.stack([f.local_quats for f in frames], 1)
        step_p = torch.stack([f.root_pos for f in frames], 1)
        # Same rotation (q and −q are equal rotations; the clip path unwraps the heading).
        dots = torch.sum(step_q * clip.local_quats, dim=-1).abs()
        torch.testing.assert_close(dots, torch.ones_like(dots), atol=1e-5, rtol=0)
        torch.testing.assert_close(step_p, clip.root_pos, atol=1e-5, rtol=0)


@pytest.mark.parametrize("name", ALL)
def test_frame_t_ignores_later_frames(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """Causality: output at frame t does not change when frames after t change."""
    model = tiny_model(name).eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 12, seed=7)
    other_q, other_r = motion(2, 12, seed=8)
    t = 6
    quats2 = torch.cat([quats[:, : t + 1], other_q[:, t + 1 :]], dim=1)
    root2 = torch.cat([root[:, : t + 1], other_r[:, t + 1 :]], dim=1)
    with torch.no_grad():
        a = model(quats, root, src, tgt)
        b = model(quats2, root2, src, tgt)
    torch.testing.assert_close(a.local_quats[:, : t + 1], b.local_quats[:, : t + 1])
    torch.testing.assert_close(a.root_pos[:, : t + 1], b.root_pos[:, : t + 1])
    assert not torch.allclose(a.local_quats[:, t + 1 :], b.local_quats[:, t + 1 :])


@pytest.mark.parametrize("name", ALL)
def test_rejects_wrong_shapes(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model(name)
    src, tgt = skeleton_pair
    quats, root = motion(2, 5)
    with pytest.raises(ValueError, match="root_pos"):
        model(quats, root[:, :-1], src, tgt)
    with pytest.raises(ValueError, match="offsets"):
        model(quats, root, src[:1], tgt)


@pytest.mark.parametrize("name", ["nkn", "pmnet"])
def test_float64_inputs_are_cast_to_the_model_dtype(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    model = tiny_model(name).eval()
    src, tgt = skeleton_pair
    quats, root = motion(2, 4)
    with torch.no_grad():
        a = model(quats, root, src, tgt)
        b = model(quats.double(), root.double(), src.double(), tgt.double())
    assert b.local_quats.dtype == torch.float32
    torch.testing.assert_close(a.local_quats, b.local_quats)
    model.reset()
    with torch.inference_mode():
        frame = model.step(quats[:, 0].double(), root[:, 0].double(), src.double(), tgt.double())
    assert frame.local_quats.dtype == torch.float32


@pytest.mark.parametrize("name", ALL)
def test_no_cpu_constants_leak_into_other_devices(
    name: str,
    tiny_model: Callable[[str], RetargetModel],
    motion: Motion,
    skeleton_pair: tuple[torch.Tensor, torch.Tensor],
) -> None:
    """Both paths run on the 'meta' device: every internal constant follows the inputs
    (a CPU constant would raise here, as it would on CUDA)."""
    model = tiny_model(name).to("meta").eval()
    src, tgt = (o.to("meta") for o in skeleton_pair)
    quats, root = (x.to("meta") for x in motion(2, 5))
    out = model(quats, root, src, tgt)
    assert out.local_quats.device.type == "meta"
    model.reset()
    with torch.inference_mode():
        frame = model.step(quats[:, 0], root[:, 0], src, tgt)
    assert frame.root_pos.device.type == "meta"
