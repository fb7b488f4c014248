"""Models on a real CMU clip, retargeted onto the robots' canonical skeletons."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.nn.features import compute_features, integrate_root, skeleton_height
from robot_retarget.nn.models.base import RetargetModel
from robot_retarget.nn.models.registry import model_names
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.loader import load_robot_config

pytestmark = pytest.mark.data

WINDOW = 60  # frames at 30 fps, as the papers train
CLIP = Path("mocap") / "02" / "02_01.bvh"  # subject 02 walking, 120 fps


@pytest.fixture(scope="module")
def clip(shared_data_dir: Path) -> HumanMotion:
    # The first 4 × 60 frames at 120 fps, subsampled to 30 fps below.
    return load_motion(shared_data_dir / CLIP, max_frames=4 * WINDOW)


def _tensors(motion: HumanMotion) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    quats = torch.tensor(motion.local_quats[::4], dtype=torch.float32)[None]
    root = torch.tensor(motion.root_pos[::4], dtype=torch.float32)[None]
    offsets = torch.tensor(motion.skeleton.offsets, dtype=torch.float32)[None]
    return quats, root, offsets


def _robot(name: str) -> torch.Tensor:
    skeleton = robot_canonical_skeleton(load_robot_config(name))
    return torch.tensor(skeleton.offsets, dtype=torch.float32)[None]


def test_features_of_a_real_walk(clip: HumanMotion) -> None:
    quats, root, offsets = _tensors(clip)
    feats = compute_features(quats, root, offsets)
    # Heading removed: the hips' left-right axis has no forward (z) component any more.
    hips_left = feats.local_pos[0, :, 14] - feats.local_pos[0, :, 18]  # LeftUpLeg − RightUpLeg
    assert float(hips_left[:, 2].abs().max()) < 1e-4
    pos, _ = integrate_root(feats.root_vel, root[:, 0], feats.yaw[:, 0])
    torch.testing.assert_close(pos, root, atol=1e-5, rtol=0)
    # A walk: the root moves a few centimetres per 30 fps frame.
    speed = torch.linalg.vector_norm(feats.root_vel[0, 1:, [0, 2]], dim=-1)
    assert 0.005 < float(speed.mean()) < 0.2


@pytest.mark.parametrize("robot", ["op3", "poppy_humanoid"])
@pytest.mark.parametrize("name", model_names())
def test_every_model_retargets_onto_the_robots(
    name: str, robot: str, clip: HumanMotion, tiny_model: Callable[[str], RetargetModel]
) -> None:
    quats, root, src = _tensors(clip)
    tgt = _robot(robot)
    model = tiny_model(name).eval()
    with torch.no_grad():
        out = model(quats, root, src, tgt)
    assert out.local_quats.shape == (1, WINDOW, 22, 4)
    norms = torch.linalg.vector_norm(out.local_quats, dim=-1)
    torch.testing.assert_close(norms, torch.ones_like(norms), atol=1e-5, rtol=0)
    assert torch.isfinite(out.root_pos).all()
    # Joints stay on the robot's bones: every FK bone length is the robot's.
    reach = torch.linalg.vector_norm(out.features.local_pos, dim=-1).amax()
    assert float(reach) <= float(skeleton_height(tgt)[0]) * 1.01


def test_copy_scaled_walks_the_robots_stride(clip: HumanMotion) -> None:
    from robot_retarget.nn.models.copy import CopyScaledModel

    quats, root, src = _tensors(clip)
    tgt = _robot("op3")
    out = CopyScaledModel()(quats, root, src, tgt)
    ratio = float(skeleton_height(tgt)[0] / skeleton_height(src)[0])
    assert 0.2 < ratio < 0.5  # a 0.5 m robot copying a grown-up
    human_path = (root[0, -1] - root[0, 0])[[0, 2]]
    robot_path = (out.root_pos[0, -1] - out.root_pos[0, 0])[[0, 2]]
    torch.testing.assert_close(robot_path, ratio * human_path, atol=2e-3, rtol=0)
