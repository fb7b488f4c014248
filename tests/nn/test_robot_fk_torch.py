"""Torch robot FK (robot_retarget.nn.robot_fk_torch) against the numpy robot FK."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.nn.robot_fk_torch import RobotFK
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config

CONFIGS = {name: load_robot_config(name) for name in ("op3", "poppy_humanoid")}


@settings(max_examples=20)
@given(seed=st.integers(0, 2**32 - 1), robot=st.sampled_from(sorted(CONFIGS)))
def test_float64_matches_numpy(seed: int, robot: str) -> None:
    config = CONFIGS[robot]
    rng = np.random.default_rng(seed)
    q = rng.uniform(config.lower, config.upper, size=(4, 2, config.num_joints))
    rot, pos = RobotKinematics(config).frame_poses(q)
    rot_t, pos_t = RobotFK(config)(torch.from_numpy(q))
    assert pos_t.dtype == torch.float64
    np.testing.assert_allclose(pos_t.numpy(), pos, atol=1e-9, rtol=0)
    np.testing.assert_allclose(rot_t.numpy(), rot, atol=1e-9, rtol=0)


def test_float32_and_subset() -> None:
    config = CONFIGS["op3"]
    q = np.random.default_rng(5).uniform(config.lower, config.upper, size=(16, config.num_joints))
    fk = RobotFK(config).to(torch.float32)
    frames = ["l_hand", "r_toe", "head_point"]
    pos32 = fk.frame_positions(torch.tensor(q, dtype=torch.float32), frames)
    assert pos32.dtype == torch.float32
    expected = RobotKinematics(config).frame_positions(q, frames)
    np.testing.assert_allclose(pos32.numpy(), expected, atol=1e-5)
    assert RobotFK(config, dtype=torch.float32).rot_k.dtype == torch.float32


def test_root_transform_matches_numpy() -> None:
    config = CONFIGS["poppy_humanoid"]
    rng = np.random.default_rng(6)
    q = rng.uniform(config.lower, config.upper, size=(3, config.num_joints))
    root = np.tile(np.eye(4), (3, 1, 1))
    root[:, :3, 3] = rng.normal(size=(3, 3))
    c, s = np.cos(0.7), np.sin(0.7)
    root[:, :2, :2] = [[c, -s], [s, c]]
    expected = RobotKinematics(config).frame_positions(q, root_transform=root)
    got = RobotFK(config).frame_positions(
        torch.from_numpy(q), root_transform=torch.from_numpy(root)
    )
    np.testing.assert_allclose(got.numpy(), expected, atol=1e-12)


def test_gradients_flow_to_joint_angles() -> None:
    config: RobotConfig = CONFIGS["op3"]
    fk = RobotFK(config)
    q = torch.tensor(config.init_pose, requires_grad=True)

    def hand(q: torch.Tensor) -> torch.Tensor:
        return fk.frame_positions(q, ["l_hand"])[0]

    assert torch.autograd.gradcheck(hand, (q,))
    out = hand(q).sum()
    out.backward()
    assert q.grad is not None
    # Only the left arm's joints move the left hand.
    moving = {config.joint_names[i] for i in torch.nonzero(q.grad).flatten().tolist()}
    assert moving <= {"l_sho_pitch", "l_sho_roll", "l_el"}
    assert moving


def test_unknown_frame_and_bad_shape() -> None:
    fk = RobotFK(CONFIGS["op3"])
    with pytest.raises(KeyError, match="no frame 'nose'"):
        fk.frame_positions(torch.zeros(20, dtype=torch.float64), ["nose"])
    with pytest.raises(ValueError, match="last axis of 20"):
        fk(torch.zeros(19, dtype=torch.float64))
