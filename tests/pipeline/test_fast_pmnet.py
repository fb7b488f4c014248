"""The numpy PMnet step equals the torch model's online step (to float32 rounding)."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.nn.inference import LoadedModel, OnlineRetargeter
from robot_retarget.nn.models.registry import build_model
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.loader import online_retargeter
from robot_retarget.runtime.pmnet import FastPMnetRetargeter
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from tests.pipeline.stream_equality import assert_same_stream, clear_of_half_turns

TOL = 2e-5


def _pmnet(seed: int = 0, causal: bool = True) -> LoadedModel:
    torch.manual_seed(seed)
    model = build_model(
        "pmnet", hidden_size=48, num_layers=3, movement_channels=16, causal_movement=causal
    )
    with torch.no_grad():
        for norm in (model.pose_norm, model.offset_norm, model.movement_norm):
            norm.mean.normal_(0.0, 0.1)
            norm.std.uniform_(0.5, 2.0)
        for param in model.parameters():
            param.add_(0.05 * torch.randn_like(param))
    return LoadedModel(name="pmnet", model=model.eval())


def _assert_same_stream(
    model: LoadedModel, src: np.ndarray, tgt: np.ndarray, quats: np.ndarray, root: np.ndarray
) -> None:
    assert_same_stream(model, src, tgt, quats, root, FastPMnetRetargeter, TOL)


def test_equals_the_torch_model_on_the_demo(demo: HumanMotion, op3: RobotConfig) -> None:
    tgt = robot_canonical_skeleton(op3).offsets
    _assert_same_stream(
        _pmnet(), demo.skeleton.offsets, tgt, demo.local_quats[:100], demo.root_pos[:100]
    )


@settings(max_examples=10, deadline=None)
@given(
    arrays(np.float64, (6, 22, 3), elements=st.floats(-3.1, 3.1)),
    arrays(np.float64, (6, 3), elements=st.floats(-5.0, 5.0)),
)
def test_equals_the_torch_model_on_wild_streams(rotvecs: np.ndarray, root: np.ndarray) -> None:
    src = default_canonical_skeleton().offsets
    quats = quat.from_rotation_vector(rotvecs)
    assume(clear_of_half_turns(quats))
    _assert_same_stream(_pmnet(1), src, 0.4 * src, quats, root)


def test_centred_movement_stays_on_torch(demo: HumanMotion) -> None:
    """The paper's centred convolutions need future frames: no online twin, as in torch."""
    src = demo.skeleton.offsets
    assert isinstance(online_retargeter(_pmnet(causal=False), src, src), OnlineRetargeter)
    assert _pmnet(causal=False).model.runtime() is None


def test_a_half_turn_in_one_frame_is_left_out_of_the_comparison() -> None:
    """The wild-stream property holds away from a heading change of ±π in one frame, where the
    sign of the turning rate is a coin toss of rounding (found by hypothesis: the root rolled
    2 rad about its forward axis, its left-right axis then pointing back along itself)."""
    rotvecs = np.full((6, 22, 3), -4.845476667818081e-08)
    rotvecs[5, 0, 2] = 2.0
    assert not clear_of_half_turns(quat.from_rotation_vector(rotvecs))
    rotvecs[5, 0] = (0.0, 1.5, 0.0)  # a quarter turn or so about the up axis
    assert clear_of_half_turns(quat.from_rotation_vector(rotvecs))
