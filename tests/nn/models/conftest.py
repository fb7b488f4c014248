"""Fixtures for the model tests: tiny models, smooth random motions, skeleton pairs."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
import pytest
import torch

from robot_retarget.nn import quaternion_torch as qt
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.batch import RetargetBatch
from robot_retarget.nn.models.registry import build_model
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from robot_retarget.skeleton.skeleton import Skeleton

# Tiny configurations: the same code paths as the paper sizes, fast on two shared cores.
TINY_CONFIGS: dict[str, dict[str, object]] = {
    "copy": {},
    "copy-scaled": {},
    "nkn": {"hidden_size": 24, "num_layers": 2},
    "pmnet": {"hidden_size": 24, "num_layers": 2, "movement_channels": 8},
    "residual": {
        "hidden_size": 24,
        "num_layers": 2,
        "denoiser_history": 3,
        "denoiser_hidden": 8,
        "root_filter_taps": 3,
    },
    "tdcn": {"channels": 8, "blocks": 2},
    "san": {"channels": (4, 8), "static_channels": 2, "kernel_size": 3},
}
TINY_DISCRIMINATORS: dict[str, dict[str, object]] = {
    "nkn": {"channels": (8, 8, 8, 8)},
    "pmnet": {"channels": (4, 4, 4, 4)},
    "tdcn": {"channels": 8, "dilations": (1, 2)},
    "san": {"channels": 8, "dilations": (1, 2)},
}


@pytest.fixture(autouse=True)
def _one_thread_and_seed() -> Iterator[None]:
    # One intra-op thread: the cores are shared and tiny ops only lose from threading.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def human() -> Skeleton:
    return default_canonical_skeleton()


def random_motion(
    batch: int, frames: int, seed: int = 0, joints: int = 22
) -> tuple[torch.Tensor, torch.Tensor]:
    """Smooth random local rotations (B, T, J, 4) and a wandering root (B, T, 3), float32."""
    g = torch.Generator().manual_seed(seed)
    base = 0.4 * torch.randn(batch, 1, joints, 3, generator=g)
    drift = 0.05 * torch.cumsum(torch.randn(batch, frames, joints, 3, generator=g), dim=1)
    quats = qt.from_rotation_vector(base + drift)
    # A turning walk: yaw drifts, root moves forward-ish, height bobs.
    yaw = 0.1 * torch.cumsum(torch.randn(batch, frames, generator=g), dim=1)
    axis = torch.tensor([0.0, 1.0, 0.0]).expand(batch, frames, 3)
    turn = qt.from_axis_angle(axis, yaw)
    quats = torch.cat([qt.mul(turn[:, :, None], quats[:, :, :1]), quats[:, :, 1:]], dim=2)
    steps = 0.03 * torch.randn(batch, frames, 3, generator=g)
    root = torch.cumsum(steps, dim=1) + torch.tensor([0.5, 0.9, -0.2])
    return quats, root


@pytest.fixture
def motion() -> Callable[..., tuple[torch.Tensor, torch.Tensor]]:
    return random_motion


def offsets_of(skeleton: Skeleton, batch: int) -> torch.Tensor:
    return torch.tensor(np.asarray(skeleton.offsets), dtype=torch.float32)[None].repeat(batch, 1, 1)


@pytest.fixture
def skeleton_pair(human: Skeleton) -> tuple[torch.Tensor, torch.Tensor]:
    """(source, target) offsets for a batch of 2: a human, and a small robot-like body."""
    src = offsets_of(human, 2)
    scale = torch.ones(22, 1)
    scale[7:10] = 0.6  # shorter left arm
    tgt = src * 0.35 * scale
    tgt[1] = src[1] * 1.2
    return src, tgt


def randomize_zero_layers(model: RetargetModel, scale: float = 0.1) -> RetargetModel:
    """Give parameters that start at exactly zero (the residual model's last layers and root
    filter, which make an untrained model equal copy-scaled) random values, so tests exercise
    the learned paths."""
    with torch.no_grad():
        for param in model.parameters():
            if not param.any():
                param.normal_(0.0, scale)
    return model


@pytest.fixture
def tiny_model() -> Callable[[str], RetargetModel]:
    def build(name: str) -> RetargetModel:
        torch.manual_seed(0)
        return randomize_zero_layers(build_model(name, **TINY_CONFIGS[name]))

    return build


def make_batch(frames: int = 24, seed: int = 0) -> RetargetBatch:
    human = default_canonical_skeleton()
    quats, root = random_motion(4, frames, seed)
    src = offsets_of(human, 4)
    tgt = src * torch.tensor([1.0, 0.5, 1.0, 0.7])[:, None, None]
    real_quats, real_root = random_motion(4, frames, seed + 1)
    return RetargetBatch(
        src_local_quats=quats,
        src_root_pos=root,
        src_offsets=src,
        tgt_offsets=tgt,
        same_skeleton=torch.tensor([True, False, True, False]),
        real_local_quats=real_quats,
        real_root_pos=real_root,
    )


@pytest.fixture
def batch() -> RetargetBatch:
    return make_batch()


@pytest.fixture
def tiny_discriminator() -> Callable[[str], torch.nn.Module]:
    from robot_retarget.nn.models.registry import build_discriminator

    def build(name: str) -> torch.nn.Module:
        torch.manual_seed(1)
        return build_discriminator(name, **TINY_DISCRIMINATORS[name])

    return build
